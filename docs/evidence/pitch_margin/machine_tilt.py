# Largest |pitch| of the rear frame and rise of its origin per episode, 40 held-out episodes:
# .venv/bin/python docs/evidence/pitch_margin/machine_tilt.py ACTOR_DIR ...  (output: machine_tilt.txt)
import sys, math, numpy as np, mujoco
from lhd_loading_ros.learning.evaluate import episode_conditions
from lhd_loading_ros.policy.actor_file import load_policy
from lhd_loading_ros.task.config import load_config
from lhd_sim_node.env import LhdLoadingEnv
cfg = load_config()
for d in sys.argv[1:]:
    pol = load_policy(d)
    env = LhdLoadingEnv(pol.variant, cfg)
    m, dd = env.sim.model, env.sim.data
    bid = m.body("rear_frame").id
    out = {}
    for i in range(40):
        seed, opts = episode_conditions(i, 2_000_000)
        obs, info = env.reset(seed=seed, options=opts)
        mx, zmax = 0.0, 0.0
        z0 = dd.xpos[bid][2]
        done = False
        while not done:
            obs, r, term, trunc, info = env.step(pol.actor(obs))
            done = term or trunc
            R = dd.xmat[bid].reshape(3, 3)
            pitch = math.degrees(math.atan2(-R[2, 0], R[0, 0]))   # nose-down positive? sign by check
            mx = max(mx, abs(pitch)); zmax = max(zmax, dd.xpos[bid][2] - z0)
        a = round(info["episode_result"].alpha_deg if "episode_result" in info else 0)
        out.setdefault(a, []).append((mx, zmax))
    for a in sorted(out):
        v = np.array(out[a]); print(f"{d} slope {a}: max |pitch| mean {v[:,0].mean():.2f} max {v[:,0].max():.2f} deg; rear rise max {100*v[:,1].max():.1f} cm")
