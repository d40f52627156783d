"""Where the shipped `policies/rld_drift_confirm` (seed 1 of runs/drift_confirm3_rld) fails a 30 deg pile told 15 deg
(75 % in `lhd experiment paper`'s slope-error table; its other four seeds 100 %): each of the cell's 20 attempts
(the table's own piles, seeds 3,930,000 + i, homogeneous; the zones built from the told slope as the end-zone node
builds them) with where the tip stopped, how long it stood there, what the actor observed (d_end, the normalised
distance to the told end zone; the drift flag) and when it first curled or lifted. Run from the repository root:
    .venv/bin/python docs/evidence/drift_confirm/stall_told_low.py [POLICY_DIR ...] \
        > docs/evidence/drift_confirm/stall_told_low.txt
(default: the shipped actor, then seeds 0-4 of runs/drift_confirm3_rld where the run is here)."""
import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from lhd_loading_ros.learning.experiment import TIME_LIMIT_S, told_observation
from lhd_loading_ros.policy.actor_file import load_policy
from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.task.randomization import NOMINAL
from lhd_sim_node.env import LhdLoadingEnv

CFG = "docs/evidence/drift_confirm/lhd_params_drift_confirm3_nominal_eval.yaml"
SLOPE, TOLD, SEED, N = 30.0, 15.0, 3_930_000, 20      # lhd experiment paper's table (b) piles for this cell
STILL_M = 0.002                                       # m of tip travel per step below which the tip stands


def attempt(env, actor, seed):
    opts = {"slope_deg": SLOPE, "material": "homogeneous",
            "conditions": replace(NOMINAL, slope_error_deg=TOLD - SLOPE)}
    obs, _ = env.reset(seed=seed, options=opts)
    told = math.radians(env.told_slope_deg)
    limit = int(round(TIME_LIMIT_S / env.p.control_dt))
    x_prev, still, longest, stall_x, first_move, d_end_at_stall = env.state.x_shovel, 0, 0, None, None, None
    for k in range(limit):
        o = told_observation(obs, told, env.p)
        a = np.clip(actor(o), -1.0, 1.0)
        if first_move is None and (env.state.z_shovel > 0.03):
            first_move = k
        obs, _, term, trunc, info = env.step(a)
        x = env.state.x_shovel
        still = still + 1 if abs(x - x_prev) < STILL_M else 0
        if still > longest:
            longest, stall_x, d_end_at_stall = still, x, float(o[10])
        x_prev = x
        if term or trunc:
            return info["episode_result"], env.zones, longest, stall_x, d_end_at_stall, first_move
    return env.result("timeout", truncated=True), env.zones, longest, stall_x, d_end_at_stall, first_move


def main(dirs):
    cfg = load_config(CFG)
    env = LhdLoadingEnv("rld", cfg, zones_from_estimate=True)
    for d in dirs:
        actor = load_policy(d).actor
        rows, ok = [], 0
        for i in range(N):
            r, z, longest, sx, dend, lift = attempt(env, actor, SEED + i)
            ok += int(r.success)
            rows.append(f"  {SEED + i} {'ok  ' if r.success else 'FAIL'} {r.loaded:5.1f} kg {r.elapsed_s:4.1f} s "
                        f"told x_min {z.x_min:.3f} m | longest stand {longest * env.p.control_dt:4.1f} s at x "
                        f"{sx if sx is not None else float('nan'):.3f} m, observed d_end {dend if dend is not None else float('nan'):+.2f} | "
                        f"tip above 3 cm from step {lift}")
        print(f"{d}: {ok} of {N} on a {SLOPE:.0f} deg pile told {TOLD:.0f} deg")
        print("\n".join(rows))


if __name__ == "__main__":
    args = sys.argv[1:]
    if not args:
        args = ["policies/rld_drift_confirm"] + [f"runs/drift_confirm3_rld/seed_{s}/final" for s in range(5)
                                                  if Path(f"runs/drift_confirm3_rld/seed_{s}/final").is_dir()]
    main(args)
