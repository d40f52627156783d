"""The arm's angle sensors off their zero (docs/training.md "The arm's angle sensors"): each actor on the held-out piles
(seed 2,000,000, stratified as `lhd eval`) with the boom's or the bucket's sensor reading `offset` deg off the true angle
(Conditions.boom_offset_deg / bucket_offset_deg: the tip, its pitch, the observation and the supervisor's end test
follow the measured angles; the load and the success test the true ones). RLC with the deployment filter; each actor
with its own parameter file where it has one.

Run from the repository root (about 5 min on 2 cores for five actors):
  .venv/bin/python docs/evidence/arm_offsets/sweep.py run rld_machine,rlc_gains,rld_told_teacher,rld,rlc 120 \
      > docs/evidence/arm_offsets/sweep.jsonl
  .venv/bin/python docs/evidence/arm_offsets/sweep.py table docs/evidence/arm_offsets/sweep.jsonl \
      > docs/evidence/arm_offsets/sweep.md
A run directory's final actor is named by its path (runs/X/seed_N/final) and evaluated on `--config`'s file:
  .venv/bin/python docs/evidence/arm_offsets/sweep.py run runs/machine_arm_rld/seed_0/final 120 --offsets=-2,0,2 \
      --config docs/evidence/arm_offsets/lhd_params_machine_arm.yaml
"""
import argparse
import json
import math
import os
import sys
from multiprocessing import Pool

import numpy as np

from lhd_loading_ros.learning.evaluate import episode_conditions, run_policy_episode
from lhd_loading_ros.policy.actor_file import load_policy
from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.task.metrics import aggregate
from lhd_loading_ros.task.randomization import Conditions
from lhd_sim_node.env import LhdLoadingEnv


def _dir_and_config(name: str, config: str | None):
    d = name if os.path.sep in name else f"policies/{name}"
    own = os.path.join(d, "lhd_params.yaml")
    return d, config or (own if os.path.exists(own) else None)


def job(args):
    name, joint, offset, episodes, config = args
    d, cfg_path = _dir_and_config(name, config)
    pol = load_policy(d)
    cfg = load_config(cfg_path)
    pol.check_config(cfg)
    env = LhdLoadingEnv(pol.variant, cfg, deploy_filter=(pol.variant == "rlc"), zones_from_estimate=True)
    cond = Conditions(**{f"{joint}_offset_deg": float(offset)})
    results, pitch = [], []
    for i in range(episodes):
        seed, opts = episode_conditions(i, 2_000_000)
        opts["conditions"] = cond
        r = run_policy_episode(env, pol.actor, seed, opts)
        results.append(r)
        pitch.append(math.degrees(r.phi_final))
    a = aggregate(results, cfg["task"]["bucket_capacity"])
    return {"actor": name, "joint": joint, "offset_deg": offset, "success": a["success_rate"], "aml": a["aml"],
            "final_pitch_mean_deg": float(np.mean(pitch)), "final_pitch_min_deg": float(np.min(pitch)),
            "below_40_deg": int(sum(p <= 40.0 for p in pitch)), "episodes": episodes}


def table(path):
    rows = [json.loads(line) for line in open(path)]
    offs = sorted({r["offset_deg"] for r in rows})
    print("success (AML kg) with one angle sensor `offset` deg off its zero (the other true); 120 held-out episodes "
          "(seed 2,000,000)")
    print("| actor | sensor | " + " | ".join(f"{o:+g} deg" for o in offs) + " |")
    print("|---|---|" + "---|" * len(offs))
    cells: dict = {}
    for r in rows:
        cells.setdefault((r["actor"], r["joint"]), {})[r["offset_deg"]] = r
    for (a, j), d in cells.items():
        print(f"| `{a}` | {j} | " + " | ".join(f"{d[o]['success']:.2f} ({d[o]['aml']:.1f})" if o in d else ""
                                              for o in offs) + " |")
    print()
    print("true final pitch, mean / least [deg] (the success test needs > 40 deg)")
    print("| actor | sensor | " + " | ".join(f"{o:+g} deg" for o in offs) + " |")
    print("|---|---|" + "---|" * len(offs))
    for (a, j), d in cells.items():
        print(f"| `{a}` | {j} | " + " | ".join(
            f"{d[o]['final_pitch_mean_deg']:.1f} / {d[o]['final_pitch_min_deg']:.1f}" if o in d else "" for o in offs)
            + " |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("cmd", choices=("run", "table"))
    ap.add_argument("what", help="run: comma-separated actors (policies/ names or actor directories); table: the jsonl")
    ap.add_argument("episodes", nargs="?", type=int, default=120)
    ap.add_argument("--offsets", default="-3,-2,-1,0,1,2,3", help="deg, comma-separated (write --offsets=-3,...)")
    ap.add_argument("--config", default=None, help="parameter file for every actor (default: each its own)")
    ap.add_argument("--joints", default="boom,bucket")
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args()
    if a.cmd == "table":
        table(a.what)
        return 0
    jobs = [(n, j, float(o), a.episodes, a.config) for n in a.what.split(",") for j in a.joints.split(",")
            for o in a.offsets.split(",")]
    with Pool(a.jobs) as p:
        for res in p.imap(job, jobs):
            print(json.dumps(res), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
