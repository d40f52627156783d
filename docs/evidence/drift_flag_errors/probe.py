"""The observed drift flag (I_drift) wrong: flipped with probability p each step (mode flip), or only missed (a
drifting wheel read as gripping: miss) or only invented (false), or k control steps late. The bridge's flags, from
wheel travel against the camera's travel, agreed with the twin's truth in 0.95-0.97 (front) and 0.81-0.90 (rear) of
the samples (docs/twin.md); nothing in training or evaluation had the flag wrong. One line per call:

    .venv/bin/python docs/evidence/drift_flag_errors/probe.py P LAG ACTOR [flip|miss|false]

`run.sh` runs the table (`table.txt`): 120 held-out episodes each (seed 2,000,000, the stratified 15-30 deg set)."""
import sys
from dataclasses import replace
from lhd_sim_node.env import LhdLoadingEnv
from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.learning.evaluate import evaluate
from lhd_loading_ros.policy.actor_file import load_policy
from collections import deque

p_flip, lag, pol, mode = float(sys.argv[1]), int(sys.argv[2]), sys.argv[3], (sys.argv[4] if len(sys.argv) > 4 else "flip")

class DriftEnv(LhdLoadingEnv):
    def _obs(self, s):
        if self.steps == 0:
            self._hist = deque(maxlen=lag + 1)
        self._hist.append(bool(s.drift))
        d = self._hist[0]
        if p_flip > 0 and self.np_random.random() < p_flip:
            d = (not d) if mode == "flip" else (False if mode == "miss" else True)
        s = replace(s, drift=d)
        return super()._obs(s)

import os
d = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "policies", pol)
cfg = load_config(d + "/lhd_params.yaml" if os.path.exists(d + "/lhd_params.yaml") else None)
P = load_policy(d)
env = DriftEnv(P.variant, cfg, deploy_filter=P.variant == "rlc", zones_from_estimate=True)
res = evaluate(env, P.actor, 120, 2_000_000, cfg["task"]["bucket_capacity"], breakdown=False)
print(pol, p_flip, lag, mode, f"success {res['success_rate']:.3f} aml {res['aml']:.1f} front {res['front_drift_pct']:.1f} rear {res['rear_drift_pct']:.1f}")
