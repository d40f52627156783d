"""Where RLC actors curl the bucket on shallow piles (2026-12-01, twenty-sixth session): for each actor directory
given, on the held-out evaluation's 15, 12 and 10 deg piles (seeds 2,000,000 + 0 / 4, homogeneous / nonhomogeneous),
where the bucket first curls, how high the tip is 0.3 m before the end zone and what the attempt loads (the measure
of docs/evidence/drift_confirm/rlc_shallow_trace.py), with the deployment filter. Run from the repository root:
    .venv/bin/python docs/evidence/curriculum_reward_test/curl_trace.py CONFIG ACTOR_DIR... > .../curl_trace.txt
e.g. CONFIG docs/evidence/steep_piles/lhd_params_steep_rlc_nominal_eval.yaml and runs/steep_rlc_reward_test/seed_{0..4}/final."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "drift_confirm"))
import rlc_shallow_trace as T  # noqa: E402

from lhd_loading_ros.learning.evaluate import episode_conditions  # noqa: E402
from lhd_loading_ros.policy.actor_file import load_policy  # noqa: E402
from lhd_loading_ros.task.config import load_config  # noqa: E402
from lhd_sim_node.env import LhdLoadingEnv  # noqa: E402


def main(config, dirs):
    env = LhdLoadingEnv("rlc", load_config(config), deploy_filter=True, zones_from_estimate=True)
    for d in dirs:
        actor = load_policy(d).actor
        print(d)
        for i in (0, 4):
            seed, opts = episode_conditions(i, 2_000_000)
            for slope in (15.0, 12.0, 10.0):
                print(f"  {slope:.0f} deg {opts['material']:14s} " + T.attempt(env, actor, seed, dict(opts, slope_deg=slope)))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:])
