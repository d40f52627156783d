"""One attempt of a final RLC actor on a 12 deg pile (nominal conditions, seed 2,000,001), step by step:
the action [wheels, boom, bucket], the observation (tip x, z, pitch; v_x; drift; boom and bucket angles, all normalised)
and the load W in kg.

    .venv/bin/python docs/evidence/wide_demo_twin_sil/trace_12deg.py runs/wide_demo_twin_mass/rlc_dr/seed_4/final ...
"""
import sys, numpy as np
from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.policy.actor_file import load_policy
from lhd_sim_node.env import LhdLoadingEnv
cfg = load_config("docs/evidence/wide_demo_twin_mass/lhd_params_wide_demo_twin_mass_nominal_eval.yaml")
env = LhdLoadingEnv("rlc", cfg)
for d in sys.argv[1:]:
    pol = load_policy(d); act = pol.actor
    obs = env.reset(seed=2_000_001, options={"slope_deg": 12.0})[0]
    print(d)
    for t in range(60):
        a = act(obs)
        obs, r, term, trunc, info = env.step(a)
        s = env.sim
        print(f"t{t:2d} a=[{a[0]:+.2f} {a[1]:+.2f} {a[2]:+.2f}] x={obs[0]:+.2f} z={obs[2]:+.2f} pitch={obs[3]:+.2f} vx={obs[4]:+.2f} drift={obs[5]:.0f} boom={obs[6]:+.2f} bkt={obs[8]:+.2f} W={s.loaded_mass:5.1f} r={r:+7.1f}")
        if term or trunc: print(info.get("outcome"), info["episode_result"].success); break
