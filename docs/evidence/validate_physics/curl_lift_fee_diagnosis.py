# Run: .venv/bin/python docs/evidence/validate_physics/curl_lift_fee_diagnosis.py asis|no_fee_h|no_fee
# Issue 13 diagnosis: how much of the lift sweep's excess over the breakout reference is the FEE's
# horizontal friction tendon (and its vertical force) still acting on the lip while the boom lifts.
import sys, math
import numpy as np
from lhd_loading_ros.task.config import load_config
import lhd_sim_node.validate as V
import lhd_sim_node.simulator as S

mode = sys.argv[1]          # "asis" | "no_fee_h" | "no_fee"
state = {"on": False}
orig_update = S.LhdSimulator._update_fee
def patched(self):
    orig_update(self)
    if state["on"]:
        if mode in ("no_fee_h", "no_fee"):
            self.model.tendon_frictionloss[self.tid_fee] = 0.0
        if mode == "no_fee":
            self.data.xfrc_applied[self.bid_bucket][:] = 0.0
S.LhdSimulator._update_fee = patched
orig_sweep = V._sweep
def sweep(*a, **k):
    state["on"] = True
    try:
        return orig_sweep(*a, **k)
    finally:
        state["on"] = False
V._sweep = sweep
cfg = load_config()
res = V.curl_lift_sweeps(cfg, slopes=(20.0, 25.0))
for case in res["cases"]:
    for motion in ("curl", "lift"):
        rows = case[motion]["bins"]
        print(mode, case["slope_deg"], motion, " ".join(f"{r['angle_deg']:g}:{r['sim_Nm']:.0f}/{r['ref_Nm']:.0f}={r['ratio']:.2f}" for r in rows))
