"""The shipped 10-35 deg actors on piles whose surface is not a plane (2026-11-28).

For each relief sd (m; correlation length 0.15 m, task/pile.py VoxelPile.roughen), 120 held-out
episodes (seed 2,000,000, the evaluation's 15-30 deg / material stratification) per actor, RLC
with the deployment filter as on the machine. An episode whose attack drive (the environment's
approach at constant speed, before the actor acts) stalls on a bump at the toe is counted apart. The
policy is told the centre slice's own slope (VoxelPile.slice_slope, what the LiDAR measures; since the
rerun of 2026-11-28). Every other condition nominal. The `rough` stress
case of `lhd eval --stress rough` is the 0.03 m row.

    .venv/bin/python docs/evidence/rough_piles/rough_sweep.py > docs/evidence/rough_piles/rough_sweep.txt
"""
import sys

from lhd_loading_ros.learning import evaluate as ev
from lhd_loading_ros.policy.actor_file import load_policy
from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.task.randomization import ROUGH_CORR, Conditions
from lhd_sim_node.env import LhdLoadingEnv
from lhd_sim_node.simulator import AttackError

SDS = (0.0, 0.03, 0.06, 0.10)
ACTORS = (("policies/rld_twin", False), ("policies/rlc_twin_sil_bc", True))
EPISODES, SEED = 120, 2_000_000


def main() -> None:
    print("actor | relief sd [m] | attack drive stalled before the actor | success (of the rest) | AML [kg] | ASL | time [s] | front drift [%] | failures (restricted / timeout / low level) | success by slope 15/20/25/30")
    for path, deploy in ACTORS:
        pol = load_policy(path)
        cfg = load_config(f"{path}/lhd_params.yaml")
        env = LhdLoadingEnv(pol.variant, cfg, deploy_filter=deploy)
        for sd in SDS:
            results, stalled = [], 0
            for i in range(EPISODES):
                s, opts = ev.episode_conditions(i, SEED)
                opts["conditions"] = Conditions(surface_sd=sd, surface_corr=ROUGH_CORR)
                try:
                    results.append(ev.run_policy_episode(env, pol.actor, s, opts))
                except AttackError:     # the environment's attack drive stalled on a bump at the toe
                    stalled += 1        # before the actor took over: not an attempt of the actor

            a = ev.aggregate(results, cfg["task"]["bucket_capacity"])
            by = [ev.aggregate([r for r in results if round(r.alpha_deg) == s_], cfg["task"]["bucket_capacity"])["success_rate"]
                  for s_ in ev.EVAL_SLOPES]
            f = (sum(r.failed for r in results), sum(r.truncated for r in results),
                 sum(r.reached_end_zone and not r.success for r in results))
            print(f"{path.split('/')[-1]} | {sd:.2f} | {stalled} | {a['success_rate']:.3f} | {a['aml']:.1f} | {a['asl']:.2f} | "
                  f"{a['elapsed_s']:.2f} | {a['front_drift_pct']:.1f} | {f[0]} / {f[1]} / {f[2]} | "
                  + "/".join(f"{b:.2f}" for b in by))
            sys.stdout.flush()


if __name__ == "__main__":
    main()
