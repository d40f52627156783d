import sys, json
from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.policy.actor_file import load_policy
from lhd_loading_ros.learning.evaluate import evaluate
from lhd_sim_node.env import LhdLoadingEnv
name, cfgp = sys.argv[1], (sys.argv[2] if len(sys.argv) > 2 else None)
cfg = load_config(cfgp)
pol = load_policy(f"policies/{name}")
out = {}
for z in (False, True):
    env = LhdLoadingEnv(pol.variant, cfg, deploy_filter=(pol.variant == "rlc"), randomize=True, zones_from_estimate=z)
    r = evaluate(env, pol.actor, 120, 2000000, cfg["task"]["bucket_capacity"])
    out["estimate" if z else "alpha_only"] = {k: r[k] for k in ("success_rate", "asl", "aml") if k in r}
print(name, json.dumps(out))
