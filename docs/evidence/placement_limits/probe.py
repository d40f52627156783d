"""Placement beyond issue 14's +-3 deg / +-5 cm (docs/supervisor.md "Placement"): every attempt with the heading
+-H deg and the lip +-O m off the pile's axis, the signs alternating as in `lhd eval --stress placement` ((i // 8) % 2,
(i // 16) % 2), 120 held-out episodes (seed 2,000,000). One line per call:

    .venv/bin/python docs/evidence/placement_limits/probe.py H O ACTOR

`run.sh` writes `table.txt`."""
import os, sys
from lhd_sim_node.env import LhdLoadingEnv
from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.task.randomization import Conditions
from lhd_loading_ros.learning.evaluate import episode_conditions, run_policy_episode
from lhd_loading_ros.task.metrics import aggregate
from lhd_loading_ros.policy.actor_file import load_policy

h, o, pol = float(sys.argv[1]), float(sys.argv[2]), sys.argv[3]
d = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "policies", pol)
own = os.path.join(d, "lhd_params.yaml")
cfg = load_config(own if os.path.exists(own) else None)
P = load_policy(d)
env = LhdLoadingEnv(P.variant, cfg, deploy_filter=P.variant == "rlc", zones_from_estimate=True)
res = []
for i in range(120):
    s, opts = episode_conditions(i, 2_000_000)
    opts["conditions"] = Conditions(heading_deg=h * (1 if (i // 8) % 2 == 0 else -1), lateral_offset=o * (1 if (i // 16) % 2 == 0 else -1))
    res.append(run_policy_episode(env, P.actor, s, opts))
a = aggregate(res, cfg["task"]["bucket_capacity"])
print(pol, h, o, f"success {a['success_rate']:.3f} aml {a['aml']:.1f}")
