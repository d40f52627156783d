"""An RLC actor on 10 deg piles (2026-12-01, twenty-sixth session): the 24 held-out piles of seeds 2,000,000 + 0..23
(their materials as the evaluation draws them) all at 10 deg, each attempt's pile friction angle (the mean over the
voxels), load and success, sorted by the friction angle. With the deployment filter, as the nodes run RLC; DF=0 in
the environment runs it without. Run from the repository root:
    .venv/bin/python docs/evidence/curriculum_reward_test/ten_deg_piles.py policies/rlc_steep \
        docs/evidence/steep_piles/lhd_params_steep_rlc_nominal_eval.yaml > docs/evidence/curriculum_reward_test/ten_deg_piles.txt
    DF=0 .venv/bin/python ... >> ...txt"""
import math
import os
import sys

import numpy as np

from lhd_loading_ros.learning.evaluate import episode_conditions, run_policy_episode
from lhd_loading_ros.policy.actor_file import load_policy
from lhd_loading_ros.task.config import load_config
from lhd_sim_node.env import LhdLoadingEnv


def main(policy_dir, config, slope=10.0):
    deploy = os.environ.get("DF", "1") == "1"
    env = LhdLoadingEnv("rlc", load_config(config), deploy_filter=deploy)
    actor = load_policy(policy_dir).actor
    rows = []
    for i in range(24):
        seed, opts = episode_conditions(i, 2_000_000)
        r = run_policy_episode(env, actor, seed, dict(opts, slope_deg=slope))
        rows.append((math.degrees(float(np.mean(env.sim.pile.phi))), r.loaded, r.success, opts["material"]))
    print(f"{policy_dir} on {slope:g} deg piles, {'with' if deploy else 'without'} the deployment filter: "
          f"{sum(s for _, _, s, _ in rows)} of {len(rows)} succeed")
    for phi, m, ok, mat in sorted(rows):
        print(f"  friction angle {phi:4.1f} deg  {mat:14s} {m:5.1f} kg  {'ok' if ok else 'FAIL'}")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], *(float(x) for x in sys.argv[3:]))
