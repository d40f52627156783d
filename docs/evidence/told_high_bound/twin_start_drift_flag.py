# Why actors fail 15 deg piles in the digital twin from rest (2026-11-30, twentieth session). The twin's first
# observations of a start from rest (bag runs/twin/.../attempt_0001 of `lhd up twin --policy
# policies/rld_told_high_rest ...`, lhd_up_twin_rld_told_high_rest_8.txt): the camera's v_x (observation index 4)
# still about 0 for two control steps while the wheels spin up, and the drift flag (index 5) raised at the second
# step, both as the machine's stack computes them. Here in process, 10 rest starts on 15 deg homogeneous piles per
# case, with those values written over the simulator's in the first three steps: both, v_x only, the flag only.
# Run: .venv/bin/python docs/evidence/told_high_bound/twin_start_drift_flag.py > docs/evidence/told_high_bound/twin_start_drift_flag.txt
import numpy as np
from dataclasses import replace
from lhd_loading_ros.learning import experiment as ex
from lhd_loading_ros.task.randomization import NOMINAL

TWIN = {1: (0.006, 1.0), 2: (0.025, 0.0), 3: (0.387, 1.0)}   # step: (v_x, drift flag) as the twin's stack observed them
for name in ("rld_told_high_rest", "rld_told_high"):
    ex._setup(f"policies/{name}/lhd_params.yaml", {"a": f"policies/{name}"})
    env = ex._env("rld")
    for mode in ("as simulated", "twin start (both)", "twin v_x only", "twin drift flag only"):
        res = []
        for ep in range(10):
            obs, _ = env.reset(seed=9100 + ep, options={"slope_deg": 15.0, "material": "homogeneous",
                                                        "conditions": replace(NOMINAL, rest_start=True)})
            k, term, trunc, first = 0, False, False, []
            while not (term or trunc):
                o = np.array(obs, dtype=np.float64)
                if k in TWIN and mode != "as simulated":
                    if mode != "twin drift flag only":
                        o[4] = TWIN[k][0]
                    if mode != "twin v_x only":
                        o[5] = TWIN[k][1]
                a = np.clip(np.asarray(ex._actor("a")(o), dtype=np.float64), -1, 1)
                if k < 4:
                    first.append(round(float(a[2]), 2))
                obs, r, term, trunc, info = env.step(a)
                k += 1
            e = info["episode_result"]
            res.append((e.success_level >= 1, round(e.loaded, 1), first))
        print(f"{name:20s} {mode:22s} success {sum(r[0] for r in res):2d}/10  kg {[r[1] for r in res]}  "
              f"bucket action, first 4 steps of the first episode {res[0][2]} (> 0 curls at full rate)")
