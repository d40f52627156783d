"""The training's demonstrations from rest with the bridge's drift window (2026-12-01, twenty-fourth session): the
recipe's teacher as every recipe before trained it (demo_drift_confirm 1: the true state's drift flags, the
simulator's window, at once) against demo_drift_confirm 3 (the flags the actor sees, the bridge's window, lifted on
only after 3 steps in a row). 10 starts from rest a cell (episode seeds 7,000,000 + k, conditions of
`--stress rest_bridge`), 15 / 20 / 30 deg piles, both materials, crowd 0.625 (the middle of the demonstrations'
range). Prints the success, the mean load and how many attempts started their lift in the first 3 steps.
Run from the repository root:
    .venv/bin/python docs/evidence/drift_confirm/demo_rest_starts.py > docs/evidence/drift_confirm/demo_rest_starts.txt"""
from dataclasses import replace

from lhd_sim_node.env import LhdLoadingEnv

from lhd_loading_ros.learning.demonstrations import DemoConfig
from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.task.randomization import DRIFT_FLAG_LAG_S, Conditions

cfg = load_config("docs/evidence/drift_confirm/lhd_params_drift_confirm3_nominal_eval.yaml")
d = DemoConfig.from_training(cfg["training"])
env = LhdLoadingEnv("rld", cfg, zones_from_estimate=True)
print("slope material       confirm  success  mean kg  lifted in the first 3 steps")
for slope in (15.0, 20.0, 30.0):
    for material in ("homogeneous", "nonhomogeneous"):
        for confirm in (1, 3):
            dd = replace(d, drift_confirm=confirm)
            ok, kg, early = 0, 0.0, 0
            for k in range(10):
                env.reset(seed=7_000_000 + k, options={"slope_deg": slope, "material": material, "conditions":
                                                       Conditions(rest_start=True, drift_flag_lag_max_s=DRIFT_FLAG_LAG_S)})
                lifted = False
                while True:
                    a = dd.action(env, 0.625)
                    if env.steps < 3:        # the push-curl maneuver's memory: its lift has started
                        lifted = lifted or bool(env._teacher_memory.get("lift"))
                    _, _, term, trunc, info = env.step(a)
                    if term or trunc:
                        r = info["episode_result"]
                        break
                ok += int(r.success)
                kg += r.loaded / 10
                early += int(lifted)
            print(f"{slope:5.0f} {material:15s} {confirm:5d}  {ok:4d}/10  {kg:7.1f}  {early:4d}/10")
