"""`lhd validate physics`: the figures of issue 13 (items 1-6), measured with real maneuvers on the
simulator (`LhdSimulator`, `LhdLoadingEnv`) and printed next to the independent references of
`reference_mechanics.py` (which never import the simulator's FEE or bucket-body code).

  1. lip resistance vs slope: the tip at an equal horizontal insertion (0.25 m) and at a fixed
     vertical depth (0.10 m), the simulator's horizontal FEE force next to the Coulomb wedge;
  2. curl and lift sweeps of a bucket driven into the pile, actuator torque buried minus the same
     motion in air, next to the breakout hand calculation;
  3. bucket capacity (ISO 7546 struck + heap; the simulator's table) at the pile density, the mass
     spilled in a full scripted attempt, and the fill the Tampier-style heuristic delivers (it curls
     until the bucket is full) next to the loader fill factors of the handbooks;
  4. front/rear drift of a fixed push-only maneuver at 1, 2 and 4 ms timesteps;
  5. the scripted maneuver's attempt duration and loaded mass over 15-30 deg piles;
  6. naive controllers' success rates (push only, curl+lift without driving, random) and whether
     pushing alone stalls before the bucket is full.

The piles of items 1-2 are homogeneous at the midpoints of the config's pile ranges (the
references then know the soil exactly); items 4-6 draw piles as training does.
docs/modeling.md, "Validation (lhd validate physics)", explains every figure and equation.
"""
from __future__ import annotations

import argparse
import copy
import json
import math
import sys
import time

import mujoco
import numpy as np

from lhd_loading_ros.task.config import ConfigError, load_config

from .reference_mechanics import (COARSE_GRAVEL_FILL, GRAVEL_DENSITY, G, BucketGeometry, Soil, breakout,
                                  bucket_capacity_at_pitch, bucket_capacity_iso7546, contents_centroid, passive_wedge,
                                  pile_surface, rating_density)

SLOPES = (15.0, 20.0, 25.0, 30.0)
WEDGE_SLOPES = (15.0, 20.0, 25.0, 30.0, 35.0)
INSERTION = 0.25       # m, equal horizontal insertion of the tip past the toe (item 1)
FIXED_DEPTH = 0.10     # m, fixed vertical depth of the tip below the face (item 1)
FLAT_ALPHA_DEG = 1.0   # the "flat" pile: a 1 deg wedge whose top is overwritten by a level layer
SWEEP_X = 0.30         # m, the tip is driven this far into the pile before the curl and lift sweeps
TIMESTEPS = (0.001, 0.002, 0.004)
MATERIALS = ("homogeneous", "nonhomogeneous")
K_UPLIFT_HI = 0.95     # upper uplift coefficient of Meyerhof & Adams (1968) for phi 30-45 deg (reference band)


# ------------------------------------------------------------------------------------- set-up
def homogeneous_config(cfg: dict) -> dict:
    """A copy of cfg whose pile ranges (every `pile` key pair X_min*/X_max* except rock sizes, rock
    counts and the rake clip) are collapsed to their midpoints."""
    out = copy.deepcopy(cfg)
    pc = out["pile"]
    for k in list(pc):
        if "_min" not in k or k.startswith(("rock_size", "rocks", "rake")):
            continue
        k2 = k.replace("_min", "_max")
        if k2 in pc and isinstance(pc[k], (int, float)) and isinstance(pc[k2], (int, float)):
            pc[k] = pc[k2] = 0.5 * (pc[k] + pc[k2])
    return out


def _homogeneous_pile(sim, alpha: float, seed: int = 0) -> None:
    """New homogeneous pile at alpha; the voxel jitter of density and cohesion is removed, so the
    reference's soil is exactly the simulator's."""
    sim.new_pile(np.random.default_rng(seed), alpha=alpha, material="homogeneous")
    p = sim.pile
    p.density[...] = float(p.density.mean())
    p.cohesion[...] = float(p.cohesion.mean())
    if hasattr(p, "_update_mass_tables"):
        p._update_mass_tables()


def pile_soil(pile) -> Soil:
    """The soil of a homogeneous pile, as the references take it."""
    g = pile.klass == 0
    return Soil(gamma=float(pile.density[g].mean()), phi=float(pile.phi[g].mean()), delta=float(pile.delta[g].mean()),
                c=float(pile.cohesion[g].mean()), c_a=float(pile.adhesion), q=float(pile.surcharge))


def _tip(sim) -> tuple[float, float, float]:
    d = sim.data
    x, _, z = d.site_xpos[sim.sid_tip]
    xm = d.site_xmat[sim.sid_tip]
    return float(x), float(z), math.atan2(xm[6], xm[0])


def _pose_tip_at(sim, x: float, surface_z=None) -> None:
    """The machine at rest in the attack pose with its tip x into the pile, the pile cut along the
    path the tip would have taken (at its height) from before the toe; one FEE period with a zero
    command so that the simulator's readings (last_fee) are those of this pose.
    surface_z: overwrite the pile's top with a level layer this high (the flat case)."""
    z_tip = sim.geometry["tip"][1]
    sl = sim.pile.slices_in(-sim.bucket_width / 2, sim.bucket_width / 2)
    if surface_z is not None:
        sim.pile.top[...] = surface_z
    sim.pile.cut(-0.05, z_tip, x, z_tip, sl)
    sim.place_machine(-x)
    sim.advance(np.zeros(3))


# ----------------------------------------------------------------------------- 1. resistance
def _rake(cfg, pitch: float) -> float:
    pc = cfg["pile"]
    return min(max(math.radians(pc["rake_attack_deg"]) - pitch, math.radians(pc["rake_min_deg"])),
               math.radians(pc["rake_max_deg"]))


def resistance_vs_slope(cfg: dict, slopes=WEDGE_SLOPES, insertion: float = INSERTION, depth: float = FIXED_DEPTH,
                        flat: bool = True) -> dict:
    from .simulator import LhdSimulator

    hc = homogeneous_config(cfg)
    # no pile of the (midpoint) material stands steeper than its friction angle (VoxelPile.generate refuses
    # one): a file whose gravel is weaker than the 35 deg wedge leaves that slope out
    slopes = [a for a in slopes if a <= hc["pile"]["phi_max_deg"] + 1e-9]
    sim = LhdSimulator(hc)
    w = hc["machine"]["bucket_width"]
    rows = {"equal_insertion": [], "fixed_depth": []}
    for mode in rows:
        cases = ([0.0] if (flat and mode == "fixed_depth") else []) + list(slopes)
        for a_deg in cases:
            alpha = math.radians(a_deg if a_deg > 0 else FLAT_ALPHA_DEG)
            _homogeneous_pile(sim, alpha)
            z_tip = sim.geometry["tip"][1]
            level = None
            if a_deg == 0.0:
                x, level = 0.30, z_tip + depth
            elif mode == "equal_insertion":
                x = insertion
            else:
                x = (depth + z_tip) / math.tan(alpha)
            _pose_tip_at(sim, x, level)
            xt, zt, pitch = _tip(sim)
            surf = level if level is not None else min(xt * math.tan(alpha), sim.pile.h)
            d_v = surf - zt
            sim_h = float(-sim.last_fee.force[0])
            ref = passive_wedge(d_v, w, pile_soil(sim.pile), 0.0 if a_deg == 0.0 else alpha, _rake(hc, pitch))
            ref_h = ref.horizontal if ref is not None else 0.0
            rows[mode].append({"slope_deg": a_deg, "x_tip": xt, "depth_m": d_v, "sim_N": sim_h, "ref_N": ref_h,
                               "ratio": sim_h / ref_h if ref_h > 0 else math.nan,
                               "ref_beta_deg": math.degrees(ref.beta) if ref is not None else math.nan})
    for mode, rs in list(rows.items()):
        sl = [r for r in rs if r["slope_deg"] > 0]
        f = [r["sim_N"] for r in sl]
        rows[mode + "_monotonic"] = bool(all(b >= a for a, b in zip(f[:-1], f[1:])))
    s = pile_soil(sim.pile)
    rows["soil"] = {"gamma": s.gamma, "phi_deg": math.degrees(s.phi), "delta_deg": math.degrees(s.delta), "c": s.c,
                    "c_a": s.c_a, "q": s.q, "width_m": w, "rake_deg": hc["pile"]["rake_attack_deg"]}
    return rows


# ---------------------------------------------------------------------------- 2. curl / lift
def _drive_in(sim, x_target: float, timeout: float = 4.0, settle: float = 0.3) -> None:
    wheels = sim.p.wheels_max
    t = 0.0
    while _tip(sim)[0] < x_target and t < timeout:
        sim.advance(np.array([wheels, 0.0, 0.0]))
        t += sim.fee_dt
    for _ in range(max(1, int(round(settle / sim.fee_dt)))):
        sim.advance(np.zeros(3))


def _sweep(sim, u, duration: float, joint: str, alpha: float, geom: BucketGeometry, soil: Soil) -> dict:
    """Run command u for duration; per FEE period: joint angle change, the joint's actuator torque,
    the lip's depth below the current and the intact surface, the lip FEE, and the reference at the
    current pose: the breakout of the column over the floor while it outweighs what the bucket
    holds, else the weight of the payload at the centroid of the bucket's section (``payload``)."""
    m, d = sim.model, sim.data
    jq = sim.bucket_q if joint == "bucket" else sim.boom_q
    act = sim.act_bucket if joint == "bucket" else sim.act_boom
    jid = m.joint("boom").id
    bid = m.body("bucket").id
    q0 = float(d.qpos[jq])
    surf = pile_surface(alpha, sim.pile.h)
    out = {k: [] for k in ("angle_deg", "torque", "lip_depth", "lip_depth_cut", "fee_N", "ref", "ref_hi", "payload",
                           "breakout", "t")}
    n = int(round(duration / sim.fee_dt))
    sl = sim.pile.slices_in(-sim.bucket_width / 2, sim.bucket_width / 2)
    for k in range(n):
        sim.advance(u)
        xt, zt, pitch = _tip(sim)
        hinge = d.xpos[bid]
        pivot = d.xanchor[jid]
        b = breakout((hinge[0], hinge[2]), pitch, geom, surf, soil, pivot_xz=(pivot[0], pivot[2]))
        bh = breakout((hinge[0], hinge[2]), pitch, geom, surf, soil, K=K_UPLIFT_HI, pivot_xz=(pivot[0], pivot[2]))
        xo = hinge[0] if joint == "bucket" else pivot[0]
        pay = float(sim.loaded_mass) * G * (contents_centroid((hinge[0], hinge[2]), pitch, geom)[0] - xo)
        i = sim.pile.column_index(xt)
        cut_top = float(sim.pile.top[sl, i].mean()) if i >= 0 else 0.0
        out["t"].append((k + 1) * sim.fee_dt)
        out["angle_deg"].append(math.degrees(abs(float(d.qpos[jq]) - q0)))
        out["torque"].append(float(d.actuator_force[act]))
        out["lip_depth"].append(float(surf(xt)) - zt)
        out["lip_depth_cut"].append(cut_top - zt)
        out["fee_N"].append(float(sim.last_fee.magnitude))
        bo, bo_hi = (b.curl_torque, bh.curl_torque) if joint == "bucket" else (b.boom_torque, bh.boom_torque)
        out["breakout"].append(bo)
        out["payload"].append(pay)
        out["ref"].append(max(bo, pay))
        out["ref_hi"].append(max(bo_hi, pay))
    return out


def _smooth(y, k: int = 5):
    y = np.asarray(y, dtype=float)
    if len(y) < k:
        return y
    return np.convolve(np.pad(y, (k // 2, k // 2), mode="edge"), np.ones(k) / k, mode="valid")


def curl_lift_sweeps(cfg: dict, slopes=(20.0,), x_target: float = SWEEP_X, curl_s: float = 2.5, lift_s: float = 1.5,
                     bins_deg=(0.0, 2.5, 5.0, 10.0, 15.0, 20.0, 25.0), lift_bins_deg=(0.0, 2.5, 5.0, 7.5, 10.0)) -> dict:
    """Drive the bucket into a homogeneous pile (arm still) until the tip is x_target in or the
    machine stalls, stop; then curl at full rate (or lift at full rate) from that pose, and the
    same motion from the same pose with the pile emptied (in air). The pile's share of the joint
    torque (buried - air, lift sign flipped: N m opposing the motion) is compared with the
    breakout reference (K0 = 1 - sin phi; ref_hi with K = 0.95)."""
    from .simulator import LhdSimulator

    hc = homogeneous_config(cfg)
    sim = LhdSimulator(hc)
    geom = BucketGeometry.from_machine(hc["machine"])
    pc = hc["paper"]["control"]
    cases = []
    for a_deg in slopes:
        alpha = math.radians(a_deg)
        case = {"slope_deg": a_deg}
        for motion, u, dur, bins in (("curl", np.array([0.0, 0.0, pc["bucket_max"]]), curl_s, bins_deg),
                                     ("lift", np.array([0.0, pc["boom_min"], 0.0]), lift_s, lift_bins_deg)):
            joint = "bucket" if motion == "curl" else "boom"
            sign = 1.0 if motion == "curl" else -1.0
            _homogeneous_pile(sim, alpha)
            soil = pile_soil(sim.pile)
            sim.place_machine(0.1)
            _drive_in(sim, x_target)
            xt, zt, _ = _tip(sim)
            qpos, act = sim.data.qpos.copy(), sim.data.act.copy()
            start = {"x_tip": xt, "lip_depth": float(pile_surface(alpha, sim.pile.h)(xt)) - zt,
                     "loaded_kg": float(sim.loaded_mass), "fee_N_before": float(sim.last_fee.magnitude)}
            buried = _sweep(sim, u, dur, joint, alpha, geom, soil)
            # the same motion in air: the same pose, the pile emptied, the bucket empty
            sim.pile.top[...] = 0.0
            sim.place_machine(-xt)
            sim.data.qpos[:] = qpos
            sim.data.qvel[:] = 0.0
            sim.data.act[:] = act
            mujoco.mj_forward(sim.model, sim.data)
            air = _sweep(sim, u, dur, joint, alpha, geom, soil)
            tb, ta = _smooth(buried["torque"]), _smooth(air["torque"])
            ab, aa = np.asarray(buried["angle_deg"]), np.asarray(air["angle_deg"])
            rows = []
            for th in bins:
                ok_b = ab.max() >= th
                ib = int(np.argmax(ab >= th)) if ok_b else -1
                ia = int(np.argmax(aa >= th)) if aa.max() >= th else -1
                if ib < 0 or ia < 0:
                    rows.append({"angle_deg": th, "sim_Nm": math.nan, "ref_Nm": math.nan, "ref_hi_Nm": math.nan,
                                 "breakout_Nm": math.nan, "payload_Nm": math.nan, "ratio": math.nan,
                                 "lip_depth": math.nan, "fee_N": math.nan})
                    continue
                s_nm = sign * (float(tb[ib]) - float(ta[ia]))
                ref = buried["ref"][ib]
                rows.append({"angle_deg": th, "sim_Nm": s_nm, "ref_Nm": ref, "ref_hi_Nm": buried["ref_hi"][ib],
                             "breakout_Nm": buried["breakout"][ib], "payload_Nm": buried["payload"][ib],
                             "ratio": s_nm / ref if ref > 0 else math.nan, "lip_depth": buried["lip_depth"][ib],
                             "fee_N": buried["fee_N"][ib]})
            below = [i for i, dd in enumerate(buried["lip_depth"]) if dd > 0.0]
            min_res_below = (min(sign * (float(tb[i]) - float(np.interp(ab[i], aa, ta))) for i in below)
                             if below else math.nan)
            case[motion] = {"start": start, "bins": rows, "reached_deg": float(ab.max()), "air_reached_deg": float(aa.max()),
                            "min_resistance_while_lip_below_face_Nm": min_res_below,
                            "series": {"buried": buried, "air": air}}
        cases.append(case)
    return {"cases": cases, "x_target": x_target}


# ------------------------------------------------------------------------------- 3. capacity
def capacity(cfg: dict, density: float, scripted_spill: list[float] | None = None) -> dict:
    """Struck/heaped volume (reference, ISO 7546 and by pitch at the config's repose angle) next to
    the simulator's capacity function, in kg at `density` (the homogeneous pile's)."""
    mc = cfg["machine"]
    geom = BucketGeometry.from_machine(mc)
    rho = float(density)
    iso = bucket_capacity_iso7546(geom)
    repose = math.radians(cfg["task"]["bucket_repose_deg"]) if "bucket_repose_deg" in cfg["task"] else math.atan(0.5)
    out = {"density": rho, "struck_L": iso["struck_m3"] * 1e3, "heaped_iso_L": iso["heaped_m3"] * 1e3,
           "struck_kg": iso["struck_m3"] * rho, "heaped_iso_kg": iso["heaped_m3"] * rho,
           "repose_deg": math.degrees(repose), "by_pitch": []}
    try:   # the simulator's capacity function (H4), if this tree has one
        from lhd_loading_ros.task.bucket_capacity import heaped_volume
    except ImportError:
        heaped_volume = None
    try:   # the fill factor on the table (2026-12-02), if this tree has one
        from lhd_loading_ros.task.bucket_capacity import fill_scale
        scale = fill_scale(cfg)
    except ImportError:
        scale = 1.0
    out["fill_factor"] = float(cfg["task"].get("bucket_fill_factor", 0.0))
    out["fill_scale"] = scale
    out["handbook_fill"] = list(COARSE_GRAVEL_FILL)
    for p_deg in (0.0, 20.0, math.degrees(iso["iso_pitch_rad"]), 60.0):
        ref = bucket_capacity_at_pitch(geom, math.radians(p_deg), repose)
        simv = heaped_volume(math.radians(p_deg), mc, repose) if heaped_volume else math.nan
        out["by_pitch"].append({"pitch_deg": p_deg, "ref_L": ref * 1e3, "sim_L": simv * 1e3, "ref_kg": ref * rho,
                                "ratio": simv / ref if ref > 0 and heaped_volume else math.nan})
    # what the simulator's table holds with the strike plane level (the rating's pose), as a share of the
    # reference's SAE heaped volume: the simulator's fill factor, against the handbook's for coarse gravel
    level = out["by_pitch"][2]
    out["table_level_L"] = level["sim_L"] * scale
    out["table_level_share_of_rating"] = level["sim_L"] * scale / out["heaped_iso_L"]
    out["heaped_kg_at_repose"] = max(r["ref_kg"] for r in out["by_pitch"])
    # the material the bucket is rated for: its 30 kg rating over its heaped volume, against the pile's
    # density range and the handbook's gravels (docs/modeling.md "The material the bucket is rated for")
    rated = float(cfg["task"]["bucket_capacity"])
    out["rated_kg"] = rated
    out["rating_density"] = rating_density(iso["heaped_m3"], rated)
    out["pile_density_range"] = [float(cfg["pile"]["density_min"]), float(cfg["pile"]["density_max"])]
    out["gravel_density"] = dict(GRAVEL_DENSITY)
    # what "full" means for the simulator: its geometric capacity, or its mass cap where it has one
    cap = cfg["task"].get("bucket_max_load")
    full = out["heaped_kg_at_repose"] * scale
    out["full_kg"] = min(full, cap) if cap else full
    if scripted_spill and all(math.isfinite(v) for v in scripted_spill):
        out["spilled_kg_scripted_mean"] = float(np.mean(scripted_spill))
        out["spilled_kg_scripted_max"] = float(np.max(scripted_spill))
    return out


def heuristic_fill(cfg: dict, slopes=SLOPES, seeds=(0, 1)) -> dict:
    """The Tampier-style heuristic (policy/tampier.py, config/tampier.yaml), which curls until the bucket
    is full, on homogeneous piles at the midpoints of the config's pile ranges (homogeneous_config): the
    volume in its bucket at the end (the simulator's loaded_volume) over the reference's SAE heaped volume,
    its delivered fill factor, next to the handbook's for coarse gravel (reference_mechanics.LOADER_FILL_FACTOR).
    Over the attempts that curled the bucket to the end (stage raise or done, whatever their outcome: most
    end in the restricted zone, with the bucket as full as it gets). The heuristic fills the bucket to the
    simulator's capacity at its final pitch, so this is an end-to-end check that what the kernel keeps is
    the fill the config names (task.bucket_fill_factor), measured on a maneuver against the reference's
    geometry; the handbook's range is the reference for that parameter, not an independent measurement."""
    from lhd_loading_ros.learning.baselines import run_tampier_episode
    from lhd_loading_ros.policy.tampier import TampierController, load_tampier_config

    hc = homogeneous_config(cfg)
    env = _env(hc)
    rho = float(hc["pile"]["density_min"])
    heaped = bucket_capacity_iso7546(BucketGeometry.from_machine(cfg["machine"]))["heaped_m3"]
    ctl = TampierController(load_tampier_config(), env.p)
    rows = []
    for a in slopes:
        for s in seeds:
            r, _ = run_tampier_episode(env, ctl, s, {"slope_deg": a, "material": "homogeneous"})
            rows.append({"slope_deg": float(a), "seed": int(s), "loaded_kg": float(r.loaded),
                         "loaded_L": float(env.sim.loaded_volume) * 1e3,
                         "curled": ctl.stage in ("raise", "done"), "success": bool(r.success)})
    curled = [x for x in rows if x["curled"]]
    fills = [x["loaded_L"] / (heaped * 1e3) for x in curled]
    lo, hi = COARSE_GRAVEL_FILL
    return {"density": rho, "heaped_iso_L": heaped * 1e3, "attempts": rows, "curled": len(curled),
            "loaded_kg_mean": float(np.mean([x["loaded_kg"] for x in curled])) if curled else math.nan,
            "loaded_L_mean": float(np.mean([x["loaded_L"] for x in curled])) if curled else math.nan,
            "fill_mean": float(np.mean(fills)) if fills else math.nan,
            "fill_min": float(np.min(fills)) if fills else math.nan,
            "fill_max": float(np.max(fills)) if fills else math.nan,
            "handbook": [lo, hi],
            # within the handbook's range, give or take the 0.03 a pass's own spread is (its range is 0.05 wide)
            "within_handbook": bool(fills and lo - 0.03 <= float(np.mean(fills)) <= hi + 0.03)}


# ---------------------------------------------------------------------------------- episodes
def _env(cfg: dict):
    from .env import LhdLoadingEnv

    return LhdLoadingEnv("rld", cfg)


def _run(env, policy, seed: int, slope: float, material: str, time_limit_s: float | None = None):
    env.reset(seed=seed, options={"slope_deg": slope, "material": material})
    limit = None if time_limit_s is None else int(round(time_limit_s / env.p.control_dt))
    while True:
        _, _, term, trunc, info = env.step(policy(env.state))
        if term or trunc:
            return info["episode_result"]
        if limit is not None and env.steps >= limit:
            return env.result("timeout", truncated=True)


def drift_vs_timestep(cfg: dict, timesteps=TIMESTEPS, slopes=SLOPES, seeds=(0,), fee_period: float = 0.02) -> dict:
    """Push-only attempts (full wheel speed, arm still, the environment's 200 steps) on the same
    piles (same seeds) at each timestep, FEE at the same 50 Hz; front and rear drift %."""
    from .scripted import push_action

    rows = []
    for dt in timesteps:
        c = copy.deepcopy(cfg)
        c["sim"]["timestep"] = dt
        c["sim"]["fee_every"] = max(1, int(round(fee_period / dt)))
        env = _env(c)
        res = [_run(env, push_action, s, a, "homogeneous") for a in slopes for s in seeds]
        rows.append({"timestep_ms": dt * 1e3, "front_pct": float(np.mean([r.front_drift_pct for r in res])),
                     "rear_pct": float(np.mean([r.rear_drift_pct for r in res])), "episodes": len(res)})
    f = [r["front_pct"] for r in rows]
    rr = [r["rear_pct"] for r in rows]
    return {"rows": rows, "front_spread_pp": max(f) - min(f), "rear_spread_pp": max(rr) - min(rr)}


def _summ(results) -> dict:
    ok = [r for r in results if r.success]
    return {"episodes": len(results), "success_rate": len(ok) / len(results),
            "time_s": float(np.mean([r.elapsed_s for r in results])),
            "mass_kg": float(np.mean([r.loaded for r in results])),
            "time_s_successful": float(np.mean([r.elapsed_s for r in ok])) if ok else math.nan,
            "mass_kg_successful": float(np.mean([r.loaded for r in ok])) if ok else math.nan,
            "front_pct": float(np.mean([r.front_drift_pct for r in results])),
            "rear_pct": float(np.mean([r.rear_drift_pct for r in results]))}


def scripted_attempts(cfg: dict, slopes=SLOPES, materials=MATERIALS, seeds=(0, 1)) -> tuple[dict, list[float]]:
    from .scripted import scripted_action

    env = _env(cfg)
    pol = lambda s: scripted_action(s, env.p.x_midgoal, lift_on_drift=True)  # noqa: E731
    out, spilled = {}, []
    for mat in materials:
        res = []
        for a in slopes:
            for s in seeds:
                res.append(_run(env, pol, s, a, mat))
                spilled.append(float(getattr(env.sim, "spilled_mass", math.nan)))
        out[mat] = _summ(res)
        out[mat]["by_slope"] = {f"{a:g}": _summ([r for r in res if abs(r.alpha_deg - a) < 1e-6]) for a in slopes}
    return out, spilled


def naive_controllers(cfg: dict, slopes=SLOPES, materials=MATERIALS, seeds=(0, 1), full_kg: float = math.nan) -> dict:
    """Success rates of push only, curl+lift without driving and random actions (each <= 20 %
    wanted), and whether pushing alone stalls (|v_x| < 2 cm/s at the end) before the bucket is full."""
    from .scripted import push_action

    env = _env(cfg)
    rng = np.random.default_rng(12345)
    ctl = {"push_only": push_action,
           "curl_lift_no_drive": lambda s: np.array([-1.0, -1.0, 1.0]),
           "random": lambda s: rng.uniform(-1.0, 1.0, 3)}
    out = {}
    push_end = []
    for name, pol in ctl.items():
        res = []
        for mat in materials:
            for a in slopes:
                for s in seeds:
                    res.append(_run(env, pol, s, a, mat))
                    if name == "push_only":
                        push_end.append((abs(env.state.v_x) < 0.02, float(env.sim.loaded_mass),
                                         float(getattr(env.sim, "spilled_mass", math.nan)), float(a), mat))
        out[name] = _summ(res)
    stalled = [e[0] for e in push_end]
    loads = [e[1] for e in push_end]
    out["push_only"]["spilled_kg_mean"] = float(np.mean([e[2] for e in push_end]))
    out["push_only"]["stalled_fraction"] = float(np.mean(stalled))
    out["push_only"]["loaded_at_end_kg_mean"] = float(np.mean(loads))
    out["push_only"]["loaded_at_end_kg_max"] = float(np.max(loads))
    out["push_only"]["full_kg"] = full_kg
    # the load a push with the arm still ends with, by slope: on 30 deg piles next to the machine's
    # stuck pushes (reference_mechanics.MACHINE_STUCK_PUSH_30DEG_KG; docs/modeling.md "Open physics findings")
    # (homogeneous piles, as the machine's)
    homo = [e for e in push_end if e[4] == "homogeneous"]
    out["push_only"]["loaded_at_end_kg_by_slope"] = {
        f"{a:g}": float(np.mean([e[1] for e in homo if e[3] == a])) for a in sorted({e[3] for e in homo})}
    out["push_stalls_before_full"] = bool(all(stalled) and (not math.isfinite(full_kg) or max(loads) < full_kg))
    out["all_at_most_20pct"] = bool(all(out[k]["success_rate"] <= 0.2 for k in ctl))
    return out


# ---------------------------------------------------------------------------------- run / io
def run(config: str | dict | None = None, quick: bool = False) -> dict:
    cfg = config if isinstance(config, dict) else load_config(config)
    t0 = time.perf_counter()
    res = {"quick": quick}
    res["resistance"] = resistance_vs_slope(cfg, slopes=(15.0, 30.0, 35.0) if quick else WEDGE_SLOPES)
    res["sweeps"] = curl_lift_sweeps(cfg, slopes=(20.0,) if quick else (15.0, 20.0, 25.0))
    slopes = (15.0, 30.0) if quick else SLOPES
    res["scripted"], spilled = scripted_attempts(cfg, slopes=slopes, seeds=(0,) if quick else tuple(range(5)))
    res["capacity"] = capacity(cfg, res["resistance"]["soil"]["gamma"], spilled)
    res["heuristic_fill"] = heuristic_fill(cfg, slopes=slopes, seeds=(0,) if quick else (0, 1))
    res["drift"] = drift_vs_timestep(cfg, timesteps=(0.002, 0.004) if quick else TIMESTEPS,
                                     slopes=(20.0,) if quick else SLOPES, seeds=(0,) if quick else (0, 1))
    res["naive"] = naive_controllers(cfg, slopes=slopes, seeds=(0,) if quick else (0, 1, 2),
                                     full_kg=res["capacity"]["full_kg"])
    res["wall_s"] = time.perf_counter() - t0
    return res


def _f(v, fmt="{:.0f}"):
    return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else fmt.format(v)


def format_report(res: dict) -> str:
    L = []
    r1 = res["resistance"]
    s = r1["soil"]
    L.append("1. Lip resistance vs slope (horizontal, N): simulator vs Coulomb passive wedge (reference_mechanics)")
    L.append(f"   soil: {s['gamma']:.0f} kg/m^3, phi {s['phi_deg']:.1f} deg, delta {s['delta_deg']:.1f} deg, c {s['c']:.0f} Pa, "
             f"q {s['q']:.0f} Pa, blade {s['width_m']:.2f} m at rake {s['rake_deg']:.0f} deg (world), depth vertical")
    for mode, title in (("equal_insertion", f"tip {INSERTION} m into the pile"), ("fixed_depth", f"tip {FIXED_DEPTH} m below the face")):
        L.append(f"   {title}: {'slope':>6} {'depth m':>8} {'sim N':>7} {'ref N':>7} {'ratio':>6}")
        for r in r1[mode]:
            L.append(f"   {'':>{len(title)}}  {r['slope_deg']:>6.0f} {r['depth_m']:>8.3f} {r['sim_N']:>7.0f} {r['ref_N']:>7.0f} "
                     f"{_f(r['ratio'], '{:.2f}'):>6}")
        L.append(f"   {'':>{len(title)}}  never decreases with slope: {r1[mode + '_monotonic']}")
    L.append("2. Curl and lift of a bucket driven into the pile: joint torque buried - in air (N m) vs breakout reference")
    for c in res["sweeps"]["cases"]:
        for motion in ("curl", "lift"):
            m = c[motion]
            st = m["start"]
            L.append(f"   {c['slope_deg']:.0f} deg, {motion}: tip {st['x_tip']:.3f} m in, lip {st['lip_depth']*100:.1f} cm below the face, "
                     f"payload {st['loaded_kg']:.1f} kg; reached {m['reached_deg']:.1f} deg (air {m['air_reached_deg']:.1f})")
            L.append(f"      {'angle':>6} {'sim Nm':>7} {'ref Nm':>7} {'ref(K.95)':>9} {'payload':>7} {'ratio':>6} {'lip cm':>6} "
                     f"{'FEE N':>6}")
            for b in m["bins"]:
                L.append(f"      {b['angle_deg']:>6.1f} {_f(b['sim_Nm']):>7} {_f(b['ref_Nm']):>7} {_f(b['ref_hi_Nm']):>9} "
                         f"{_f(b['payload_Nm']):>7} "
                         f"{_f(b['ratio'], '{:.2f}'):>6} {_f(b['lip_depth'] * 100 if math.isfinite(b['lip_depth']) else math.nan, '{:.1f}'):>6} "
                         f"{_f(b['fee_N']):>6}")
            L.append(f"      least resistance while the lip is below the face: {_f(m['min_resistance_while_lip_below_face_Nm'])} N m")
    cp = res["capacity"]
    L.append(f"3. Capacity at {cp['density']:.0f} kg/m^3: struck {cp['struck_L']:.2f} L = {cp['struck_kg']:.1f} kg, "
             f"heaped (ISO 7546, 2:1) {cp['heaped_iso_L']:.2f} L = {cp['heaped_iso_kg']:.1f} kg; "
             f"at the repose {cp['repose_deg']:.1f} deg by pitch:")
    for b in cp["by_pitch"]:
        L.append(f"      pitch {b['pitch_deg']:>5.1f} deg: reference {b['ref_L']:6.2f} L ({b['ref_kg']:.1f} kg), "
                 f"simulator's static heap {_f(b['sim_L'], '{:.2f}')} L, ratio {_f(b['ratio'], '{:.3f}')}; its table "
                 f"(x {cp['fill_scale']:.3f}, the fill factor) {_f(b['sim_L'] * cp['fill_scale'], '{:.2f}')} L")
    gd = cp["gravel_density"]
    L.append(f"   rated {cp['rated_kg']:.0f} kg over the heaped {cp['heaped_iso_L']:.2f} L: rated for loose material of "
             f"{cp['rating_density']:.0f} kg/m^3; the pile is {cp['pile_density_range'][0]:.0f}-{cp['pile_density_range'][1]:.0f} "
             f"kg/m^3 (handbook gravel: " + ", ".join(f"{k} {v:.0f}" for k, v in gd.items()) + ")")
    hb = cp["handbook_fill"]
    L.append(f"   fill factor (task.bucket_fill_factor) {cp['fill_factor']:g}"
             + (" (none: the whole static heap)" if cp["fill_factor"] == 0 else "")
             + f": the table holds {cp['table_level_L']:.2f} L with the strike plane level, "
             f"{cp['table_level_share_of_rating']:.3f} of the SAE heaped rating; loaders deliver {hb[0]:.2f}-{hb[1]:.2f} of it in "
             "uniform aggregates of 12 mm and over (Caterpillar Performance Handbook ed. 47, Tables p. 30-2)")
    hf = res.get("heuristic_fill")
    if hf:
        L.append(f"   the Tampier-style heuristic (curls until full) on homogeneous {hf['density']:.0f} kg/m^3 piles: "
                 f"{hf['curled']} of {len(hf['attempts'])} attempts curled to the end with {_f(hf['loaded_kg_mean'], '{:.1f}')} kg, "
                 f"{_f(hf['loaded_L_mean'], '{:.2f}')} L in the bucket: "
                 f"a delivered fill of {_f(hf['fill_mean'], '{:.2f}')} ({_f(hf['fill_min'], '{:.2f}')}-{_f(hf['fill_max'], '{:.2f}')}) "
                 f"of the SAE heaped {hf['heaped_iso_L']:.2f} L; handbook {hf['handbook'][0]:.2f}-{hf['handbook'][1]:.2f}: "
                 f"within (+-0.03): {hf['within_handbook']}")
    if "spilled_kg_scripted_mean" in cp:
        L.append(f"   spilled in the scripted attempts: mean {cp['spilled_kg_scripted_mean']:.1f} kg, max {cp['spilled_kg_scripted_max']:.1f} kg")
    dr = res["drift"]
    L.append("4. Drift of the push-only maneuver vs timestep:")
    for r in dr["rows"]:
        L.append(f"      {r['timestep_ms']:.0f} ms: front {r['front_pct']:5.1f} %, rear {r['rear_pct']:5.1f} % ({r['episodes']} attempts)")
    L.append(f"      spread: front {dr['front_spread_pp']:.1f} pp, rear {dr['rear_spread_pp']:.1f} pp (issue: within 5 pp)")
    L.append("5. Scripted maneuver (paper's real machine: 3-6 s, 21-28 kg in successful attempts):")
    for mat, v in res["scripted"].items():
        L.append(f"      {mat:>15}: success {v['success_rate']:.2f}, time {v['time_s']:.2f} s, mass {v['mass_kg']:.1f} kg "
                 f"(successful: {_f(v['time_s_successful'], '{:.2f}')} s, {_f(v['mass_kg_successful'], '{:.1f}')} kg), "
                 f"drift front {v['front_pct']:.0f} % rear {v['rear_pct']:.0f} %")
    nv = res["naive"]
    L.append("6. Naive controllers over 15-30 deg, homogeneous and rocky (each <= 20 % wanted):")
    for k in ("push_only", "curl_lift_no_drive", "random"):
        L.append(f"      {k:>18}: success {nv[k]['success_rate']:.2f} ({nv[k]['episodes']} attempts), mass {nv[k]['mass_kg']:.1f} kg")
    p = nv["push_only"]
    L.append(f"      push only: stalled in {p['stalled_fraction']*100:.0f} % of attempts with {p['loaded_at_end_kg_mean']:.1f} kg "
             f"(max {p['loaded_at_end_kg_max']:.1f}; spilled {_f(p['spilled_kg_mean'], '{:.1f}')}) against a full bucket of {_f(p['full_kg'], '{:.1f}')} kg: "
             f"stalls before full: {nv['push_stalls_before_full']}; all <= 20 %: {nv['all_at_most_20pct']}")
    by = p.get("loaded_at_end_kg_by_slope", {})
    if by:
        from .reference_mechanics import MACHINE_STUCK_PUSH_30DEG_KG as ref
        L.append("      push only on homogeneous piles, load at the end by slope: " + ", ".join(f"{a} deg {v:.1f} kg" for a, v in by.items())
                 + "; the paper's machine stuck pushing on 30 deg piles (told 15 deg): "
                 + " / ".join(f"{k} {v:.1f}" for k, v in ref.items()) + " kg"
                 + (f" (the simulator's 30 deg push: {by['30'] / np.mean(list(ref.values())):.2f} of it)" if "30" in by else "")
                 + "; not like for like: the machine stalled 'with the bucket of material full' after its own lift and"
                 " curl; the same experiment with the paper-protocol actor is `lhd experiment paper --rld policies/rld_paper`"
                 " (table b; docs/modeling.md \"Open physics findings\")")
    L.append(f"({res['wall_s']:.0f} s)")
    return "\n".join(L)


def write_plots(res: dict, out_dir: str) -> list[str]:
    import os

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(out_dir, exist_ok=True)
    paths = []
    r1 = res["resistance"]
    fig, axs = plt.subplots(1, 2, figsize=(10, 4))
    for ax, mode, title in ((axs[0], "equal_insertion", f"tip {INSERTION} m into the pile"),
                            (axs[1], "fixed_depth", f"tip {FIXED_DEPTH} m below the face")):
        a = [r["slope_deg"] for r in r1[mode]]
        ax.plot(a, [r["sim_N"] for r in r1[mode]], "o-", label="simulator (lip FEE)")
        ax.plot(a, [r["ref_N"] for r in r1[mode]], "s--", label="Coulomb wedge (reference)")
        ax.set_xlabel("face slope, deg")
        ax.set_ylabel("horizontal resistance, N")
        ax.set_title(title)
        ax.legend()
    fig.tight_layout()
    paths.append(os.path.join(out_dir, "resistance_vs_slope.png"))
    fig.savefig(paths[-1], dpi=100)
    plt.close(fig)
    cases = res["sweeps"]["cases"]
    fig, axs = plt.subplots(1, 2, figsize=(10, 4))
    for ax, motion, unit in ((axs[0], "curl", "bucket joint"), (axs[1], "lift", "boom joint")):
        for c in cases:
            b = c[motion]["bins"]
            l, = ax.plot([x["angle_deg"] for x in b], [x["sim_Nm"] for x in b], "o-", label=f"{c['slope_deg']:.0f} deg: simulator")
            ax.plot([x["angle_deg"] for x in b], [x["ref_Nm"] for x in b], "s--", color=l.get_color(), label=f"{c['slope_deg']:.0f} deg: breakout ref")
        ax.set_xlabel(f"{motion} angle from the buried pose, deg")
        ax.set_ylabel(f"torque at the {unit}, buried - air, N m")
        ax.legend(fontsize=7)
    fig.tight_layout()
    paths.append(os.path.join(out_dir, "curl_lift_sweeps.png"))
    fig.savefig(paths[-1], dpi=100)
    plt.close(fig)
    dr = res["drift"]["rows"]
    fig, ax = plt.subplots(figsize=(5, 4))
    ax.plot([r["timestep_ms"] for r in dr], [r["front_pct"] for r in dr], "o-", label="front")
    ax.plot([r["timestep_ms"] for r in dr], [r["rear_pct"] for r in dr], "s-", label="rear")
    ax.axhline(21, color="C0", ls=":", label="paper RLD real front 21 %")
    ax.axhline(67, color="C1", ls=":", label="paper RLD real rear 67 %")
    ax.set_xlabel("timestep, ms")
    ax.set_ylabel("drift, % of the attempt")
    ax.legend(fontsize=7)
    fig.tight_layout()
    paths.append(os.path.join(out_dir, "drift_vs_timestep.png"))
    fig.savefig(paths[-1], dpi=100)
    plt.close(fig)
    sc = res["scripted"]
    fig, axs = plt.subplots(1, 2, figsize=(10, 4))
    for mat, v in sc.items():
        a = [float(k) for k in v["by_slope"]]
        axs[0].plot(a, [x["time_s"] for x in v["by_slope"].values()], "o-", label=mat)
        axs[1].plot(a, [x["mass_kg"] for x in v["by_slope"].values()], "o-", label=mat)
    axs[0].axhspan(3, 6, color="0.9", label="paper real 3-6 s")
    axs[1].axhspan(21, 28, color="0.9", label="paper real 21-28 kg")
    axs[0].set_ylabel("attempt duration, s")
    axs[1].set_ylabel("loaded mass, kg")
    for ax in axs:
        ax.set_xlabel("pile slope, deg")
        ax.legend(fontsize=7)
    fig.tight_layout()
    paths.append(os.path.join(out_dir, "scripted_attempts.png"))
    fig.savefig(paths[-1], dpi=100)
    plt.close(fig)
    return paths


def _jsonable(o):
    """The report as JSON values: the per-step series left out, non-finite numbers as null."""
    from lhd_loading_ros.task.json_out import jsonable

    return jsonable(o, drop_keys=("series",))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="lhd validate physics",
                                 description="issue 13's physics figures: the simulator next to independent references")
    ap.add_argument("--plots", metavar="DIR", help="write the PNG figures here")
    ap.add_argument("--json", action="store_true", help="print the figures as JSON")
    ap.add_argument("--config", default=None, help="parameter file (default: config/lhd_params.yaml)")
    ap.add_argument("--quick", action="store_true", help="fewer slopes and attempts (smoke test, ~20 s)")
    a = ap.parse_args(argv)
    try:
        cfg = load_config(a.config)
    except ConfigError as exc:
        print(f"lhd validate physics: {exc}", file=sys.stderr)
        return 1
    lo, hi = cfg["paper"]["episode"]["alpha_min_deg"], cfg["paper"]["episode"]["alpha_max_deg"]
    if lo > min(SLOPES) or hi < max(SLOPES):
        # the references are worked at the paper's piles; the environment refuses a slope outside the file's range
        print(f"lhd validate physics: its cases are piles of {min(SLOPES):g}-{max(SLOPES):g} deg (the paper's, where "
              f"the hand references are worked), and {a.config or 'the parameter file'} has piles of {lo:g}-{hi:g} deg "
              f"(paper.episode.alpha_min_deg / alpha_max_deg); give a file whose range covers "
              f"{min(SLOPES):g}-{max(SLOPES):g} deg", file=sys.stderr)
        return 2
    res = run(cfg, quick=a.quick)
    if a.plots:
        res["plots"] = write_plots(res, a.plots)
    print(json.dumps(_jsonable(res), allow_nan=False) if a.json else format_report(res))
    if a.plots and not a.json:
        print("plots: " + ", ".join(res["plots"]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
