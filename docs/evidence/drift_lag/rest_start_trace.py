"""What the five seeds trained with the bridge's drift window do at a start from rest on a 15 deg pile: the first
six observations (drift flag, v_x, tip x and z, normalised) and the actions (wheels, boom, bucket), for the
held-out evaluation's first four 15 deg episodes (seed 2,000,000 + 0, 4, 8, 12), under `--stress rest` (the
simulator's drift window) and `rest_bridge` (the bridge's); then the first two actions of episode 0 from rest, and the first at the attack speed, for
these seeds and for the same recipe's seeds trained without the lag (runs/told_high_demos_pile_zones_rest_rld, on
its own evaluation file). Run from the repository root after the trainings of docs/training.md "The bridge's drift
window in training" and "Both settings with a quarter of the episodes from rest":
    .venv/bin/python docs/evidence/drift_lag/rest_start_trace.py runs/told_high_demos_pile_zones_rest_driftlag_rld \
        docs/evidence/told_high_bound/lhd_params_steep_push_curl_told_high_demos_pile_zones_rest_driftlag_nominal_eval.yaml \
        > docs/evidence/drift_lag/rest_start_trace.txt"""
import sys

import numpy as np

from lhd_loading_ros.learning.evaluate import episode_conditions
from lhd_loading_ros.policy.actor_file import load_policy
from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.task.randomization import stress_conditions
from lhd_sim_node.env import LhdLoadingEnv

run, cfg = sys.argv[1], load_config(sys.argv[2])
env = LhdLoadingEnv("rld", cfg, randomize=False, zones_from_estimate=True)
for seed in range(5):
    actor = load_policy(f"{run}/seed_{seed}/final").actor
    for stress in ("rest", "rest_bridge"):
        for i in (0, 4, 8, 12):
            s, opts = episode_conditions(i, 2_000_000)
            opts["conditions"] = stress_conditions(stress, i, cfg)
            obs, _ = env.reset(seed=s, options=opts)
            rows = []
            while True:
                a = np.clip(actor(obs), -1.0, 1.0)
                rows.append(f"fl {int(obs[5])} vx {obs[4]:+.2f} x {obs[0]:+.2f} z {obs[2]:+.2f} "
                            f"a ({a[0]:+.2f} {a[1]:+.2f} {a[2]:+.2f})")
                obs, _, term, trunc, info = env.step(a)
                if term or trunc:
                    break
            res = info["episode_result"]
            print(f"seed {seed} {stress:11s} episode {i:2d} {opts['material']:14s} success {int(res.success)} "
                  f"{res.loaded:5.1f} kg {res.steps:3d} steps | " + " | ".join(rows[:6]))

print("\nfirst two actions (wheels, boom, bucket) from rest and the first at the attack speed, 15 deg, episode 0:")
E = "docs/evidence/told_high_bound"
for other, file in ((run, sys.argv[2]),
                    ("runs/told_high_demos_pile_zones_rest_rld",
                     f"{E}/lhd_params_steep_push_curl_told_high_demos_pile_zones_rest_nominal_eval.yaml")):
    c = load_config(file)
    e = LhdLoadingEnv("rld", c, randomize=False, zones_from_estimate=True)
    for seed in range(5):
        actor = load_policy(f"{other}/seed_{seed}/final").actor
        s, opts = episode_conditions(0, 2_000_000)
        opts["conditions"] = stress_conditions("rest", 0, c)
        obs, _ = e.reset(seed=s, options=opts)
        a0 = np.clip(actor(obs), -1.0, 1.0)
        obs, *_ = e.step(a0)
        a1 = np.clip(actor(obs), -1.0, 1.0)
        obs, _ = e.reset(seed=s, options={k: v for k, v in opts.items() if k != "conditions"})
        an = np.clip(actor(obs), -1.0, 1.0)       # the same pile at the attack speed (nominal start)
        print(f"{other} seed {seed}: from rest step 0 ({a0[0]:+.2f} {a0[1]:+.2f} {a0[2]:+.2f}), "
              f"step 1 ({a1[0]:+.2f} {a1[1]:+.2f} {a1[2]:+.2f}); at the attack speed (v_x {obs[4]:+.2f}) step 0 "
              f"({an[0]:+.2f} {an[1]:+.2f} {an[2]:+.2f})")
