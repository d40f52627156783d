"""The machine case (placed by hand, from rest, on a rough pile) on every slope of the machine actors' trained
10-35 deg, 30 episodes a slope (the held-out seeds 2,000,000 + i, i = 0, 4, ..., 116: the same conditions as
`lhd eval --stress machine`'s episodes i, both materials in turn), each actor with its own parameter file, RLC
with the deployment filter. From the repository root:

    .venv/bin/python docs/evidence/machine_case/slopes.py > docs/evidence/machine_case/slopes.txt

`slopes.py rld_machine` runs only the named actors of policies/ (rows to add to the table); with STRESS=machine_bridge
in the environment, the machine case with the bridge's drift flags (docs/evidence/drift_confirm/, 2026-12-01).
"""
import os
import sys

from lhd_sim_node.env import LhdLoadingEnv

from lhd_loading_ros.learning.evaluate import run_policy_episode
from lhd_loading_ros.policy.actor_file import load_policy, own_config
from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.task.randomization import stress_conditions

SLOPES = (10.0, 12.0, 13.0, 14.0, 15.0, 17.5, 22.5, 27.5, 32.5, 35.0)
STRESS = os.environ.get("STRESS", "machine")
print(f"{'machine case' if STRESS == 'machine' else STRESS}, 30 episodes a slope: successes (mean load of all attempts, kg)")
print("| actor | " + " | ".join(f"{s:g} deg" for s in SLOPES) + " |")
print("|---" * (len(SLOPES) + 1) + "|")
for a in sys.argv[1:] or ("rld_gains", "rlc_gains"):
    d = f"policies/{a}"
    cfg = load_config(own_config(d))
    pol = load_policy(d).check_config(cfg)
    env = LhdLoadingEnv(pol.variant, cfg, deploy_filter=(pol.variant == "rlc"), zones_from_estimate=True)
    cells = []
    for slope in SLOPES:
        rs = []
        for i in range(0, 120, 4):
            opts = {"slope_deg": slope, "material": ("homogeneous", "nonhomogeneous")[(i // 4) % 2],
                    "conditions": stress_conditions(STRESS, i, cfg)}
            rs.append(run_policy_episode(env, pol.actor, 2_000_000 + i, opts))
        cells.append(f"{sum(r.success for r in rs)}/{len(rs)} ({sum(r.loaded for r in rs) / len(rs):.1f})")
    print(f"| `{a}` | " + " | ".join(cells) + " |", flush=True)
