"""Where the RLC seeds of a run curl on the held-out 15 deg piles and a 10 deg pile of the same draws: the trace of
docs/evidence/drift_confirm/rlc_shallow_trace.py with the 10-40 deg RLC evaluation file. From the repository root:
    .venv/bin/python docs/evidence/margin8/shallow_trace.py runs/steep_rlc_margin8 [runs/settle_margin8_rlc ...] \
        > docs/evidence/margin8/shallow_trace.txt"""
import sys
runs = sys.argv[1:]
sys.argv=[sys.argv[0]]
sys.path.insert(0, "docs/evidence/drift_confirm")
import rlc_shallow_trace as t
t.CFG = "docs/evidence/steep_piles/lhd_params_steep_rlc_nominal_eval.yaml"
t.main(runs)
