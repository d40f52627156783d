"""Why the drift-confirm recipe's RLC seeds fail shallow piles (2026-12-01, twenty-fifth session): for each seed's final
actor (RLC with the deployment filter, as the nodes run it) and for the recipe's shipped RLD, on the held-out
evaluation's 15 deg piles (seeds 2,000,000 + 0 / 4, homogeneous / nonhomogeneous) and a 10 deg pile of the same
draw, where the bucket first curls (the tip's x when the bucket angle has risen 0.1 rad from its start), how high the
tip is when it passes the told end zone's x_min - 0.3 m, and what the attempt loads. Run from the repository root
after the trainings of docs/training.md "The same recipe as RLC, with the confirming teacher":
    .venv/bin/python docs/evidence/drift_confirm/rlc_shallow_trace.py [RUN ...] > docs/evidence/drift_confirm/rlc_shallow_trace.txt
(default runs/drift_confirm3_rlc, and runs/drift_confirm3_level_push_rlc where it is here). With ACTOR=best in the
environment, each seed's best checkpoint (best/) instead of its final actor:
    ACTOR=best .venv/bin/python docs/evidence/drift_confirm/rlc_shallow_trace.py runs/drift_confirm3_level_push_rlc \
        | tail -n +6 >> docs/evidence/drift_confirm/rlc_shallow_trace.txt   (the RLD block once)"""
import os
import sys
from pathlib import Path

import numpy as np

from lhd_loading_ros.learning.evaluate import episode_conditions
from lhd_loading_ros.policy.actor_file import load_policy
from lhd_loading_ros.task.config import load_config
from lhd_sim_node.env import LhdLoadingEnv

CFG = "docs/evidence/drift_confirm/lhd_params_drift_confirm3_nominal_eval.yaml"
CURLED = 0.1      # rad the bucket has turned from its start
ACTOR = os.environ.get("ACTOR", "final")


def attempt(env, actor, seed, opts):
    obs, _ = env.reset(seed=seed, options=opts)
    z = env.zones
    phi0, curl_x, z_before = env.state.phi_shovel, None, None
    while True:
        obs, _, term, trunc, info = env.step(np.clip(actor(obs), -1.0, 1.0))
        st = env.state
        if curl_x is None and st.phi_shovel - phi0 > CURLED:
            curl_x = st.x_shovel
        if z_before is None and st.x_shovel >= z.x_min - 0.3:
            z_before = st.z_shovel
        if term or trunc:
            r = info["episode_result"]
            return (f"x_min {z.x_min:.2f} m | bucket curled at x {curl_x if curl_x is not None else float('nan'):.2f} m | "
                    f"tip {z_before if z_before is not None else float('nan'):.3f} m high 0.3 m before x_min | "
                    f"{r.loaded:5.1f} kg {'ok' if r.success else 'FAIL'} {r.elapsed_s:.1f} s")


def main(runs):
    cfg = load_config(CFG)
    actors = [("policies/rld_drift_confirm (RLD)", "rld", "policies/rld_drift_confirm")]
    for run in runs:
        for s in range(5):
            d = Path(run) / f"seed_{s}" / ACTOR
            if d.is_dir():
                actors.append((f"{run} seed {s} ({ACTOR})", "rlc", str(d)))
    for name, v, d in actors:
        env = LhdLoadingEnv(v, cfg, deploy_filter=(v == "rlc"), zones_from_estimate=True)
        actor = load_policy(d).actor
        print(name)
        for i in (0, 4):
            seed, opts = episode_conditions(i, 2_000_000)
            for slope in (15.0, 10.0):
                o = dict(opts, slope_deg=slope)
                print(f"  {slope:.0f} deg {o['material']:14s} " + attempt(env, actor, seed, o))


if __name__ == "__main__":
    main(sys.argv[1:] or [r for r in ("runs/drift_confirm3_rlc", "runs/drift_confirm3_level_push_rlc") if Path(r).is_dir()])
