"""Would a model of the pile face meeting the front tyres change what the Tampier-style heuristic
loads in the simulator? Traces the heuristic's attempts (the simulator as shipped, the paper's 10 s)
and reports, per attempt: the load when the front tyres' leading edge first passes the pile's toe
(the earliest moment a wheel/face model could act), the farthest the tyres get past the toe, the
intact face's height there, a hand estimate of the face's passive resistance on two tyres at that
height, the pile's horizontal force on the bucket then, the machine's largest nose-down pitch, and
how the attempt ended.

Hand estimate (independent of the simulator's FEE code): Coulomb's passive earth pressure on a
vertical wall of height z and width b, the surface rising at the pile's slope beta = alpha ahead of
it, wall friction delta (Das, Principles of Geotechnical Engineering, Coulomb's passive case):

    K_p = cos^2(phi) / (cos(delta) (1 - sqrt(sin(phi + delta) sin(phi + beta) / (cos(delta) cos(beta))))^2)
    P_p = 1/2 gamma z^2 K_p b,  horizontal: P_p cos(delta)

with delta = 0 (a smooth wall: the lower estimate) and delta = 2/3 phi (a rough tyre; Coulomb's
planar wedge is known to overestimate rough walls, and on steep rising faces the root's argument
nears 1 and the wedge locks: printed as "locks" where the argument exceeds 0.9). Tyre width b = 0.10 m: an assumption (the MJCF tyres
are spheres and have no width). The drive's limit: 4 wheel motors x 30 N m / 0.137 m = 876 N.

Run: .venv/bin/python docs/evidence/tampier_face/trace_tampier.py > docs/evidence/tampier_face/trace.txt
     .venv/bin/python docs/evidence/tampier_face/trace_tampier.py --detail 25 2000000 > docs/evidence/tampier_face/detail_25deg.txt
"""
import math
import sys

import numpy as np
from lhd_sim_node.env import LhdLoadingEnv

from lhd_loading_ros.policy.tampier import TampierController, load_tampier_config
from lhd_loading_ros.task.config import load_config

TYRE_WIDTH = 0.10
G = 9.81


def coulomb_kp(phi, delta, beta):
    s = math.sin(phi + delta) * math.sin(phi + beta) / (math.cos(delta) * math.cos(beta))
    return math.cos(phi) ** 2 / (math.cos(delta) * (1.0 - math.sqrt(s)) ** 2)


def coulomb_root(phi, delta, beta):
    return math.sin(phi + delta) * math.sin(phi + beta) / (math.cos(delta) * math.cos(beta))


def face_on_two_tyres(z, gamma, phi, delta, beta):
    return 2 * 0.5 * gamma * z * z * coulomb_kp(phi, delta, beta) * TYRE_WIDTH * math.cos(delta)


def detail(env, ctl, alpha, seed, material="homogeneous"):
    """Every 5th control period of one attempt: stage, tip, boom, pitch, load, the pile's horizontal
    (tendon) and vertical (xfrc) forces on the bucket, the machine's nose-down pitch, the rear axle's
    height and where the whole machine's centre of mass lies relative to the front axle."""
    sim = env.sim
    m, d = sim.model, sim.data
    fl, rl = m.body("wheel_fl").id, m.body("wheel_rl").id
    env.reset(seed=seed, options={"slope_deg": alpha, "material": material})
    ctl.reset()
    z = sim.zones
    print(f"{alpha:g} deg {material}, seed {seed}; the machine and its load: {m.body_subtreemass[sim.bid_rear]:.1f} kg at the start")
    print("step stage | tip x, z [m] | boom [deg] | bucket pitch [deg] | W [kg] | FEE x / z [N] | machine pitch [deg] | "
          "rear axle z [m] | CoM - front axle [m] | bucket body [kg]")
    while True:
        u = ctl.step(env.state, (z.x_min, z.x_max, z.z_min))
        _, _, term, trunc, info = env.step_actuator(np.asarray(u))
        s = env.state
        if env.steps % 5 == 0 or term or trunc:
            print(f"{env.steps:3d} {ctl.stage:8s} | {s.x_shovel:.2f}, {s.z_shovel:.2f} | {math.degrees(s.phi_boom):6.1f} | "
                  f"{math.degrees(s.phi_shovel):5.1f} | {info['loaded_mass']:4.1f} | "
                  f"{m.tendon_frictionloss[sim.tid_fee]:4.0f} / {d.xfrc_applied[sim.bid_bucket, 2]:5.0f} | "
                  f"{math.degrees(sim.machine_pitch()):5.1f} | {d.xpos[rl, 2]:.3f} | "
                  f"{d.subtree_com[sim.bid_rear, 0] - d.xpos[fl, 0]:+.3f} | {m.body_mass[sim.bid_bucket]:.1f}")
        if term or trunc or env.steps >= 100:
            print("ended:", "restricted zone" if term and info["episode_result"].failed else
                  ("success" if term and info["episode_result"].success else "10 s"))
            return


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--detail":      # --detail ALPHA SEED
        cfg = load_config(None)
        env = LhdLoadingEnv("rld", cfg)
        return detail(env, TampierController(load_tampier_config(), env.p), float(sys.argv[2]), int(sys.argv[3]))
    cfg = load_config(sys.argv[1] if len(sys.argv) > 1 else None)
    mc = cfg["machine"]
    r = mc["wheel_radius"]
    drive = 4 * mc["wheel_torque_limit"] / r
    env = LhdLoadingEnv("rld", cfg)
    ctl = TampierController(load_tampier_config(), env.p)
    sim = env.sim
    m, d = sim.model, sim.data
    fl, fr = m.body("wheel_fl").id, m.body("wheel_fr").id
    print(f"drive limit {drive:.0f} N; tyre width {TYRE_WIDTH} m (assumed); 10 s attempts, seed 2,000,000 + k")
    print("slope material k | W at tyres on toe | tyres past toe max, face h | face on 2 tyres, delta 0 / 2/3 phi "
          "| bucket FEE then | max pitch | tip z end (floor) | W end | end")
    for material in ("homogeneous", "nonhomogeneous"):
        for alpha in (15.0, 20.0, 25.0, 30.0):
            for k in range(3):
                env.reset(seed=2_000_000 + k, options={"slope_deg": alpha, "material": material})
                ctl.reset()
                z = sim.zones
                pile = sim.pile
                gamma = float(np.median(pile.density[pile.klass == 0])) * G
                phi = float(pile.phi[pile.klass == 0].flat[0])
                a = math.radians(alpha)
                w_touch, fee_touch, lead_max, max_pitch = None, None, -9.0, 0.0
                end = "limit"
                while True:
                    u = ctl.step(env.state, (z.x_min, z.x_max, z.z_min))
                    _, _, term, trunc, info = env.step_actuator(np.asarray(u))
                    lead = max(d.xpos[fl, 0], d.xpos[fr, 0]) + r
                    lead_max = max(lead_max, lead)
                    max_pitch = max(max_pitch, math.degrees(sim.machine_pitch()))
                    if w_touch is None and lead > 0.0:
                        w_touch, fee_touch = info["loaded_mass"], float(m.tendon_frictionloss[sim.tid_fee])
                    if term or trunc:
                        res = info["episode_result"]
                        end = "success" if res.success else ("restricted" if res.failed else "timeout")
                        break
                    if env.steps >= 100:
                        res = env.result("timeout", truncated=True)
                        end = "success (10 s)" if res.success else "timeout (10 s)"
                        break
                h = max(0.0, lead_max) * math.tan(a)
                lo = face_on_two_tyres(h, gamma, phi, 0.0, a)
                rough = ("locks" if coulomb_root(phi, 2 * phi / 3, a) > 0.9
                         else f"{face_on_two_tyres(h, gamma, phi, 2 * phi / 3, a):4.0f} N")
                wt = "never" if w_touch is None else f"{w_touch:5.1f} kg"
                ft = "-" if fee_touch is None else f"{fee_touch:4.0f} N"
                print(f"{alpha:4.0f} {material[:5]} {k} | {wt:>8} | {lead_max:+.2f} m, {h:.3f} m | {lo:4.0f} N / {rough:>6} "
                      f"| {ft:>6} | {max_pitch:4.1f} deg | {env.state.z_shovel:.2f} ({z.z_min:.2f}) m "
                      f"| {info['loaded_mass']:4.1f} kg | {end}")


if __name__ == "__main__":
    main()
