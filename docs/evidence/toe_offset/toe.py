"""The pile's toe off the pile frame's origin by dx (docs/end_zone.md "Frames"): the end-zone node moves the zones with the
LiDAR's toe, the policy's x observation is the pile frame's (build_observation's fixed observation zone), so it is off by dx.
Run from the repository root: .venv/bin/python docs/evidence/toe_offset/toe.py rld_machine,rld_gains,rld_told_teacher,rlc_gains 120
nominal,machine " -0.1,-0.05,0,0.05,0.1" > docs/evidence/toe_offset/toe.jsonl  (about 3 min on 2 cores), then
.venv/bin/python docs/evidence/toe_offset/toe.py table docs/evidence/toe_offset/toe.jsonl > docs/evidence/toe_offset/toe.txt"""
import sys, json, os
from multiprocessing import Pool
import numpy as np
from lhd_loading_ros.policy.actor_file import load_policy
from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.learning.evaluate import evaluate
from lhd_sim_node.env import LhdLoadingEnv

def job(args):
    name, cond, dx = args
    d = f"policies/{name}"
    pol = load_policy(d)
    cfgp = f"{d}/lhd_params.yaml" if os.path.exists(f"{d}/lhd_params.yaml") else None
    cfg = load_config(cfgp)
    env = LhdLoadingEnv(pol.variant, cfg, deploy_filter=(pol.variant == "rlc"), zones_from_estimate=True)
    shift = 2.0 * dx / env.p.x_obs
    def actor(o):
        o = np.array(o, dtype=np.float32); o[0] = np.clip(o[0] + shift, -1, 1); return pol.actor(o)
    r = evaluate(env, actor, int(sys.argv[2]), 2_000_000, cfg["task"]["bucket_capacity"], breakdown=True,
                 stress=None if cond == "nominal" else cond)
    return name, cond, dx, r["success_rate"], r["aml"], {k: round(v["success_rate"], 3) for k, v in r["by_slope"].items()}, r["failures"]

def table(path):
    """toe.txt from toe.jsonl: `toe.py table docs/evidence/toe_offset/toe.jsonl > docs/evidence/toe_offset/toe.txt`."""
    rows = [json.loads(line) for line in open(path)]
    dxs = sorted({r[2] for r in rows})
    print("success (AML kg) with the x observation off by dx (the toe at dx in the pile frame); 120 held-out "
          "episodes, seed 2,000,000")
    print("| actor | condition | " + " | ".join(f"dx {dx:+.2f} m" for dx in dxs) + " |")
    print("|---|---|" + "---|" * len(dxs))
    cells = {}
    for n, c, dx, s, m, *_ in rows:
        cells.setdefault((n, c), {})[dx] = (s, m)
    for (n, c), d in cells.items():
        print(f"| `{n}` | {c} | " + " | ".join(f"{d[dx][0]:.3f} ({d[dx][1]:.1f})" for dx in dxs) + " |")


if __name__ == "__main__":
    if sys.argv[1] == "table":
        table(sys.argv[2])
        sys.exit(0)
    names = sys.argv[1].split(","); conds = sys.argv[3].split(","); dxs = [float(v) for v in sys.argv[4].split(",")]
    jobs = [(n, c, dx) for n in names for c in conds for dx in dxs]
    with Pool(2) as p:
        for res in p.imap(job, jobs):
            print(json.dumps(res), flush=True)
