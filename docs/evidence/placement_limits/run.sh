#!/usr/bin/env bash
# From the repository root (about 2 min on 2 cores):  bash docs/evidence/placement_limits/run.sh
set -euo pipefail
E=docs/evidence/placement_limits
for p in rld_machine rlc_gains rld rld_drift_confirm rld_drift_confirm_margin8; do   # rld_drift_confirm added 2026-12-01 (twenty-fifth session), rld_drift_confirm_margin8 2026-12-02
  for ho in "3 0.05" "6 0" "10 0" "0 0.10" "0 0.15" "6 0.10"; do
    set -- $ho
    .venv/bin/python $E/probe.py "$1" "$2" "$p"
  done
done > $E/table.txt
