"""The paper's heuristic baseline in simulation: the Tampier-style controller (policy/tampier.py)
driving the Gymnasium environment in actuator units, scored with the paper's metrics.

The controller sees the environment's task state (the same quantities the policy node rebuilds
from the topics: v_x, joints, drift flags, the bucket tip) and the episode's end zone, and
commands rad/s through `env.step_actuator`, as the sim node does with /lhd/cmd. An attempt ends
at the end zone (success), the restricted zone (failure) or `time_limit_s`: by default the
paper's 10 s timeout of the real-world attempts (its Tampier row was measured under it), not the
simulated episodes' 200 steps. The figures come twice: over every attempt (the simulator's
convention, metrics.aggregate) and over the successful attempts only (the paper's real-world
table: "the performance metrics for loaded material, execution time, and those associated with
drift, are computed considering only successful loading attempts").

`python -m lhd_loading_ros.learning.baselines --episodes 40 --slopes 15,20,25,30 --material
homogeneous` prints the table (docs/baselines.md); `lhd eval --controller tampier` is the same call.
"""
from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

from lhd_loading_ros.task import json_out
from lhd_loading_ros.learning.evaluate import EVAL_MATERIALS, EVAL_SLOPES
from lhd_loading_ros.policy.tampier import TampierController, TampierParams, load_tampier_config
from lhd_loading_ros.task.metrics import EpisodeResult, aggregate

PAPER_TIMEOUT_S = 10.0      # the real-world attempts' timeout (paper, experimental settings)


def conditions(i: int, seed: int, slopes=EVAL_SLOPES, materials=EVAL_MATERIALS) -> tuple[int, dict]:
    """Episode i of a stratified set: slope slopes[i % n], material materials[(i // n) % m], seed
    seed + i. With the defaults, learning.evaluate.episode_conditions (the actors' set)."""
    n = len(slopes)
    return seed + i, {"slope_deg": float(slopes[i % n]), "material": materials[(i // n) % len(materials)]}


def run_tampier_episode(env, ctl: TampierController, seed: int, options: dict,
                        time_limit_s: float | None = PAPER_TIMEOUT_S) -> tuple[EpisodeResult, dict]:
    """One attempt; returns its EpisodeResult and a trace (per step: stage, command, tip x/z,
    pitch, loaded mass) for tests and plots."""
    env.reset(seed=seed, options=options)
    ctl.reset()
    z = env.zones      # what the end-zone node gives the controller (the estimate's, with a slope error)
    end_zone = (z.x_min, z.x_max, z.z_min)
    limit = None if time_limit_s is None else max(1, int(round(time_limit_s / env.p.control_dt)))
    s0 = env.state
    trace = {"stage": [], "command": [], "x": [s0.x_shovel], "z": [s0.z_shovel], "phi": [s0.phi_shovel],
             "loaded": [env.sim.loaded_mass], "end_zone": end_zone}
    while True:
        u = ctl.step(env.measured_state, end_zone)     # what the heuristic's sensors give it
        _, _, term, trunc, info = env.step_actuator(np.asarray(u))
        s = env.state
        trace["stage"].append(ctl.stage)
        trace["command"].append(tuple(u))
        trace["x"].append(s.x_shovel)
        trace["z"].append(s.z_shovel)
        trace["phi"].append(s.phi_shovel)
        trace["loaded"].append(info["loaded_mass"])
        if term or trunc:
            return info["episode_result"], trace
        if limit is not None and env.steps >= limit:
            return env.result("timeout", truncated=True), trace


def _successful(results: list[EpisodeResult], bucket_capacity: float) -> dict | None:
    ok = [r for r in results if r.success]
    return aggregate(ok, bucket_capacity) if ok else None


def evaluate_tampier(env, episodes: int, seed: int, bucket_capacity: float, tp: TampierParams | None = None,
                     slopes=EVAL_SLOPES, materials=EVAL_MATERIALS,
                     time_limit_s: float | None = PAPER_TIMEOUT_S) -> dict:
    """`episodes` stratified attempts (conditions()); the aggregate over all of them
    (metrics.aggregate keys), `successful` (the same over successful attempts only, None when
    there are none), `by_slope` / `by_material` (each with its own `successful`), `failures`
    (restricted zone, timeout, end zone below SL 1, collision never detected) and `episodes_list`."""
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    if not slopes or not materials:
        raise ValueError("slopes and materials must each name at least one condition")
    lo, hi = math.degrees(env.p.alpha_min), math.degrees(env.p.alpha_max)
    bad = [a for a in slopes if not (lo - 1e-9 <= float(a) <= hi + 1e-9)]
    if bad:
        raise ValueError(f"slope(s) {bad} deg outside the simulator's range [{lo:g}, {hi:g}] deg")
    ctl = TampierController(tp or load_tampier_config(), env.p)
    t0 = time.perf_counter()
    results, rows = [], []
    for i in range(episodes):
        s, opts = conditions(i, seed, slopes, materials)
        r, trace = run_tampier_episode(env, ctl, s, opts, time_limit_s)
        results.append(r)
        rows.append({**r.to_dict(), "seed": s, "collision_step": ctl.collision_step,
                     "last_stage": ctl.stage, "max_tip_z": max(trace["z"])})
    out = aggregate(results, bucket_capacity)
    out["successful"] = _successful(results, bucket_capacity)

    def group(rs):
        g = aggregate(rs, bucket_capacity)
        g["successful"] = _successful(rs, bucket_capacity)
        return g

    out["by_slope"] = {f"{a:g}": group(rs) for a in slopes
                       if (rs := [r for r in results if round(r.alpha_deg, 6) == round(float(a), 6)])}
    out["by_material"] = {m: group(rs) for m in materials if (rs := [r for r in results if r.material == m])}
    out["failures"] = {
        "restricted_zone": sum(r.failed for r in results),
        "timeout": sum(r.truncated and not r.success for r in results),
        "end_zone_low_level": sum(r.reached_end_zone and not r.success for r in results),
        "collision_not_detected": sum(row["collision_step"] is None for row in rows),
    }
    # the paper's rule: an attempt that meets both success conditions at the timeout is a success
    out["successes_at_timeout"] = sum(r.truncated and r.success for r in results)
    out["episodes_list"] = rows
    out["time_limit_s"] = time_limit_s
    out["wall_s"] = time.perf_counter() - t0
    return out


def format_tampier(res: dict) -> str:
    """The table: all attempts, then the successful ones (the paper's convention), by slope and material."""
    head = (f"{'':>18} {'n':>3} {'success':>7} {'AML kg':>7} {'time s':>6} {'front %':>7} {'rear %':>6} | "
            f"{'successful only: AML kg':>23} {'time s':>6} {'front %':>7} {'rear %':>6}")

    def row(name, r):
        ok = r.get("successful")
        tail = (f"{ok['aml']:>23.1f} {ok['elapsed_s']:>6.2f} {ok['front_drift_pct']:>7.1f} {ok['rear_drift_pct']:>6.1f}"
                if ok else f"{'(no successful attempt)':>23} {'-':>6} {'-':>7} {'-':>6}")
        return (f"{name:>18} {r['episodes']:>3} {r['success_rate']:>7.2f} {r['aml']:>7.1f} {r['elapsed_s']:>6.2f} "
                f"{r['front_drift_pct']:>7.1f} {r['rear_drift_pct']:>6.1f} | {tail}")

    lim = res.get("time_limit_s")
    lines = [f"Tampier-style heuristic, time limit {'%g s' % lim if lim else 'the environment max_steps'}",
             head, row("all", res)]
    lines += [row(f"{k} deg", v) for k, v in res.get("by_slope", {}).items()]
    lines += [row(k, v) for k, v in res.get("by_material", {}).items()] if len(res.get("by_material", {})) > 1 else []
    f = res["failures"]
    lines.append(f"failures: restricted zone {f['restricted_zone']}, timeout {f['timeout']}, end zone below SL 1 "
                 f"{f['end_zone_low_level']}; collision never detected in {f['collision_not_detected']}; successes at "
                 f"the timeout (both conditions met, the paper's rule) {res.get('successes_at_timeout', 0)}")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m lhd_loading_ros.learning.baselines",
                                 description="the Tampier-style heuristic on the simulator, with the paper's metrics")
    ap.add_argument("--episodes", type=int, default=120)
    ap.add_argument("--seed", type=int, default=2_000_000)
    ap.add_argument("--slopes", default=",".join(f"{a:g}" for a in EVAL_SLOPES), help="comma-separated, deg")
    ap.add_argument("--material", default="both", choices=("both",) + EVAL_MATERIALS)
    ap.add_argument("--time-limit", type=float, default=PAPER_TIMEOUT_S,
                    help="s per attempt (paper's real attempts: 10); 0: the environment's max_steps")
    ap.add_argument("--config", default=None, help="lhd_params.yaml")
    ap.add_argument("--tampier-config", default=None, help="tampier.yaml")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    return run_cli(a.episodes, a.seed, a.slopes, a.material, a.time_limit, a.config, a.tampier_config, a.json)


def run_cli(episodes: int, seed: int, slopes: str, material: str, time_limit: float, config: str | None,
            tampier_config: str | None, as_json: bool) -> int:
    """What `lhd eval --controller tampier` does: prints the table (or JSON); exit status 0, 1 for
    a bad parameter file, 2 for a bad argument."""
    from lhd_sim_node.env import LhdLoadingEnv   # the simulator only where it runs

    from lhd_loading_ros.task.config import ConfigError, load_config

    # each bad argument named alone (they were listed all at once, the good ones too: a review)
    parts = str(slopes).split(",")
    try:
        slope_list = tuple(float(v) for v in parts)
    except ValueError:
        slope_list = ()
    problems = []
    if episodes < 1:
        problems.append(f"--episodes {episodes}: expected >= 1")
    if seed < 0:
        problems.append(f"--seed {seed}: expected >= 0")
    if not slope_list or not all(math.isfinite(v) for v in slope_list):
        problems.append(f"--slopes {slopes!r}: expected comma-separated degrees, e.g. 15,20,25,30")
    if not (math.isfinite(time_limit) and time_limit >= 0):
        problems.append(f"--time-limit {time_limit}: expected seconds >= 0 (0: the environment's 200 steps)")
    if problems:
        print(f"tampier eval: {'; '.join(problems)}", file=sys.stderr)
        return 2
    try:
        cfg = load_config(config)
        tp = load_tampier_config(tampier_config)
    except ConfigError as exc:
        print(f"tampier eval: {exc}", file=sys.stderr)
        return 1
    try:
        env = LhdLoadingEnv("rld", cfg)    # variant irrelevant: commands go through step_actuator
        materials = EVAL_MATERIALS if material == "both" else (material,)
        res = evaluate_tampier(env, episodes, seed, cfg["task"]["bucket_capacity"], tp, slope_list, materials,
                               time_limit if time_limit > 0 else None)
    except ValueError as exc:          # a slope outside the environment's range
        print(f"tampier eval: {exc}", file=sys.stderr)
        return 2
    res.update({"controller": "tampier", "seed": seed})
    print(json_out.dumps(res) if as_json else format_tampier(res))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
