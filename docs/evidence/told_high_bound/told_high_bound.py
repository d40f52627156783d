# .venv/bin/python docs/evidence/told_high_bound/told_high_bound.py > docs/evidence/told_high_bound/told_high_bound.txt
# (2026-11-30, sixteenth session; about 1 min on one core)
"""How much can any controller load from a 15 deg pile told 30 deg, with the zones built from the told slope
(as the end-zone node builds them on the machine)? Issue 14 asks for loaded mass within 15 % of the no-error
load for every told error in -15..+15 deg. Measured here with the scripted maneuver (policy/maneuver.py), on the
parameter file of policies/rld_told_teacher, homogeneous piles, seeds 0-4:

1. push: wheels at full speed, arm still, until the push stalls (the deepest the tip gets on the floor);
2. the teacher's maneuver on the told zones (push to x_midgoal, then curl and lift, wheels at `crowd` of full
   speed, stopped within 0.2 m of the told x_max below z_min): lift points 0.50-0.70 m, crowd 0 / 0.3 / 0.625 (lift also on the first drift);
   success, payload, and the material over the bucket's opening when the lift starts (the bucket body's m_over:
   voxel mass between the plate and the surface before the lip cut it);
3. the same maneuvers told the truth (15 deg), and the best lift point, for the no-error load;
4. a pre-curled push (found by a review with a fresh context, 2026-11-30): wheels full, boom still, the bucket
   curled to 0.30 rad from x = 0.40 m (the attack pose's capacity, 22 kg, grows to about 31 kg at 10 deg of curl
   and the push no longer stalls at 0.65-0.77 m), lift and curl from 0.05 m short of the told x_max (or on a
   stall or drift) with the wheels full, the wheels stopped once x > x_max - (0.45 (z_min - z) + 0.04).

The hand calculation beside it is the wedge's material over the plate when the tip is at x on a pile of slope
alpha: the plate runs from x - 0.30 m to x (bucket_tip_ahead_of_hinge), 0.39 m wide (the bucket's inside; the
pile's voxels span 0.40 m), its top about 1.5 cm over the floor in the attack pose; surface z = x tan(alpha):
m = rho w (tan(alpha) (x^2 - (x - 0.30)^2) / 2 - 0.015 x 0.30). It bounds what a bucket lifted where it stands
carries out, not what a bucket that keeps cutting while it rises can load (item 4).
"""
import math
from dataclasses import replace

import numpy as np

from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.task.randomization import NOMINAL
from lhd_sim_node.env import LhdLoadingEnv
from lhd_sim_node.scripted import scripted_action

CFG = "policies/rld_told_teacher/lhd_params.yaml"
cfg = load_config(CFG)
env = LhdLoadingEnv("rld", cfg, zones_from_estimate=True)
SLOPE = 15.0
LB, W_IN, PLATE_Z = 0.30, 0.39, 0.015


def hand_over(x, alpha_deg, rho):
    t = math.tan(math.radians(alpha_deg))
    x0 = max(x - LB, 0.0)
    return rho * W_IN * (t * (x * x - x0 * x0) / 2 - PLATE_Z * (x - x0))


def attempt(seed, told, policy):
    opts = {"slope_deg": SLOPE, "material": "homogeneous",
            "conditions": replace(NOMINAL, slope_error_deg=told - SLOPE)}
    env.reset(seed=seed, options=opts)
    z = env.zones
    lift = None
    for _ in range(100):
        s = env.state
        a = policy(env, z)
        if lift is None and (a[1] < 0.0 or a[2] > -1.0):
            lift = (s.x_shovel, env.sim.loaded_mass, env.sim.body.report()["m_over"])
        _, _, term, trunc, info = env.step(a)
        if term or trunc:
            return info["episode_result"], lift, z, env
    return env.result("timeout", truncated=True), lift, z, env


def push(env, z):
    return np.array([1.0, 1.0, -1.0])


def teacher(xm, crowd):
    return lambda env, z: scripted_action(env.measured_state, xm, crowd=crowd, pre_curl=0.3, lift_on_drift=True,
                                          end_zone=(z.x_max, z.z_min), end_zone_stop=0.2)


def trained_teacher(env, z):
    """The `teacher` controller of lhd experiment paper (its lift point: the told zones' x_min)."""
    from lhd_loading_ros.learning.demonstrations import demo_action
    from lhd_loading_ros.learning.experiment import teacher_setting
    return demo_action(env, *teacher_setting(env.cfg), measured=True)


rho = None
print(f"parameter file {CFG}; a {SLOPE:g} deg homogeneous pile, seeds 0-4")
print("\n1. push only, arm still, to the stall")
for seed in range(5):
    r, _, z, e = attempt(seed, SLOPE, push)
    s = e.state
    rho = float(np.median(e.sim.pile.density))
    print(f"   seed {seed}: tip stalls at x {s.x_shovel:.3f} m with {r.loaded:.1f} kg in the bucket; over the plate "
          f"{e.sim.body.report()['m_over']:.1f} kg (hand, wedge at {rho:.0f} kg/m^3: "
          f"{hand_over(s.x_shovel, SLOPE, rho):.1f} kg); pile's own x_max {z.x_max:.3f} m")

for told in (30.0, 15.0):
    print(f"\n2. the teacher's maneuver told {told:g} deg (zones from the told slope)")
    best = {}
    for xm in (0.50, 0.55, 0.60, 0.65, 0.70):
        for crowd in (0.0, 0.3, 0.625):
            rows = []
            for seed in range(5):
                r, lift, z, e = attempt(seed, told, teacher(xm, crowd))
                rows.append((r.success, r.loaded, lift, z.x_max))
            ok = [m for s_, m, _, _ in rows if s_]
            lifts = [lf for _, _, lf, _ in rows if lf is not None]
            lx = np.mean([lf[0] for lf in lifts]) if lifts else float("nan")
            lm = np.mean([lf[1] for lf in lifts]) if lifts else float("nan")
            lo = np.mean([lf[2] for lf in lifts]) if lifts else float("nan")
            mean_ok = float(np.mean(ok)) if ok else float("nan")
            print(f"   lift from {xm:.2f} m, crowd {crowd:.1f}: {len(ok)}/5 succeed, {mean_ok:.1f} kg over the successes; "
                  f"at the lift (x {lx:.3f} m) {lm:.1f} kg in the bucket and {lo:.1f} kg over the plate "
                  f"(hand {hand_over(lx, SLOPE, rho):.1f} kg); told x_max {rows[0][3]:.3f} m")
            if ok:
                best[(xm, crowd)] = (len(ok), mean_ok)
    if best:
        k = max(best, key=lambda k: (best[k][0], best[k][1]))
        print(f"   best told {told:g}: lift from {k[0]:.2f} m, crowd {k[1]:.1f}: {best[k][0]}/5, {best[k][1]:.1f} kg")
    res = [attempt(seed, told, trained_teacher)[0] for seed in range(5)]
    ok = [r.loaded for r in res if r.success]
    print(f"   the `teacher` controller (lift at the told x_min, crowd and pre-curl of the parameter file): "
          f"{len(ok)}/5, {np.mean(ok) if ok else float('nan'):.1f} kg over the successes")


def precurled(env, z, mem={}):
    s = env.measured_state
    if env.steps == 0:
        mem.clear()
    if not mem.get("lift"):
        if s.x_shovel >= z.x_max - 0.05 or (env.steps > 5 and s.v_x < 0.02 and s.x_shovel > 0.2) or s.drift:
            mem["lift"] = True
    bucket = 1.0 if (s.x_shovel >= 0.40 and s.phi_shovel < 0.30) else -1.0
    if not mem.get("lift"):
        return np.array([1.0, 1.0, bucket])
    wheels = 1.0
    if s.z_shovel < z.z_min and s.x_shovel > z.x_max - (0.45 * (z.z_min - s.z_shovel) + 0.04):
        wheels = -1.0
    return np.array([wheels, -1.0, 1.0])


print("\n4. a pre-curled push (0.30 rad from 0.40 m), lift 0.05 m short of the told x_max, wheels full")
for told in (30.0, 15.0):
    res = [attempt(seed, told, precurled)[0] for seed in range(5)]
    ok = [r.loaded for r in res if r.success]
    print(f"   told {told:g} deg: {len(ok)}/5 succeed, {np.mean(ok) if ok else float('nan'):.1f} kg over the successes "
          f"({', '.join(f'{r.loaded:.1f}' for r in res)} kg)")
