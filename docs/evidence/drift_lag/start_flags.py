"""The drift flags the first four observations of a start from rest carry: the simulator's own window (the
control period since the last command) against the bridge's (a period ending 0-140 ms before the observation,
randomization.drift_flag_lag_max_s 0.14, drawn each step as training draws it). 20 starts from rest each on
15 and 30 deg piles, full wheels, arm still. Run from the repository root:
    .venv/bin/python docs/evidence/drift_lag/start_flags.py > docs/evidence/drift_lag/start_flags.txt"""
import numpy as np

from lhd_loading_ros.task.randomization import Conditions
from lhd_sim_node.env import LhdLoadingEnv

N = 20
for slope in (15.0, 30.0):
    env = LhdLoadingEnv("rld", slope_deg=slope)
    own, bridge = np.zeros(4), np.zeros(4)
    for seed in range(N):
        env.reset(seed=seed, options={"conditions": Conditions(rest_start=True, drift_flag_lag_max_s=0.14)})
        for k in range(4):
            obs, *_ = env.step(np.array([1.0, 0.0, 0.0], dtype=np.float32))
            own[k] += any(env.sim.wheel_drift())
            bridge[k] += obs[5]
    print(f"{slope:g} deg, share of {N} starts flagged at observations 1-4: simulator's window "
          f"{' '.join(f'{v / N:.2f}' for v in own)}; bridge's window {' '.join(f'{v / N:.2f}' for v in bridge)}")
