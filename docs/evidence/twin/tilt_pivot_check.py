# The tilting machine in the simulator: do the front wheels stay on the floor while the rear lifts,
# and how well does the ArUco node's tilt model (perception/aruco.tilted_base_position: rotation about the
# front axle's floor contact) give the marker's height? The shipped RLD on 20 30-deg piles of the
# ship's confirmation seeds; episodes whose machine pitched more than 4 deg are printed.
# Run: .venv/bin/python docs/evidence/twin/tilt_pivot_check.py
import math, numpy as np
from lhd_sim_node.env import LhdLoadingEnv
from lhd_loading_ros.policy.actor_file import load_policy
from lhd_loading_ros.perception.geometry import rpy_matrix
from lhd_loading_ros.task.kinematics import nose_down_pitch
pol = load_policy("policies/rld")
env = LhdLoadingEnv("rld", deploy_filter=False)
m = env.sim.model; d = env.sim.data
wid = {w: m.body(w).id for w in ("wheel_fl","wheel_fr","wheel_rl","wheel_rr")}
M_BASE = np.array([-0.10, 0.0, 0.213]); WB = 0.80; RW = 0.137
worst = []
for seed in range(3000000, 3000020):
    obs, _ = env.reset(seed=seed, options={"slope_deg": 30.0, "material": "homogeneous"})
    rows = []
    while True:
        R = d.xmat[env.sim.bid_rear].reshape(3,3); p = d.xpos[env.sim.bid_rear].copy()
        base = d.qpos[:3].copy()
        rows.append((nose_down_pitch(R), base, R.copy(), d.xpos[wid["wheel_fl"]][2], d.xpos[wid["wheel_rl"]][2]))
        obs, r, te, tr, info = env.step(np.clip(pol.actor(obs), -1, 1))
        if te or tr: break
    mx = max(abs(r_[0]) for r_ in rows)
    if mx < math.radians(4): continue
    errs_model, errs_level = [], []
    for pitch, base, R, zf, zr in rows:
        yaw = math.atan2(R[1,0], R[0,0]); roll = math.atan2(R[2,1], R[2,2])
        Rm = rpy_matrix(roll, pitch, yaw)
        c = np.array([WB, 0, -RW]) if pitch >= 0 else np.array([0, 0, -RW])
        zb_model = -(Rm @ c)[2]
        hm_true = base[2] + (R @ M_BASE)[2]
        hm_model = zb_model + (Rm @ M_BASE)[2]
        errs_model.append(hm_true - hm_model); errs_level.append(hm_true - 0.35)
    i = int(np.argmax([abs(r_[0]) for r_ in rows]))
    print(f"seed {seed}: max pitch {math.degrees(mx):.2f} deg; base z at max {rows[i][1][2]:.3f}; front wheel z {rows[i][3]:.3f} rear {rows[i][4]:.3f}; "
          f"marker height error: model max {max(map(abs,errs_model))*1000:.1f} mm, level max {max(map(abs,errs_level))*1000:.1f} mm; base z level {rows[0][1][2]:.4f}")
