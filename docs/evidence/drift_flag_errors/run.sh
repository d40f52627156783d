#!/usr/bin/env bash
# From the repository root (about 1.5 min on 2 cores):  bash docs/evidence/drift_flag_errors/run.sh
set -euo pipefail
E=docs/evidence/drift_flag_errors
for p in rld_machine rlc_gains rld rlc; do
  for args in "0 0 flip" "0.05 0 flip" "0.1 0 flip" "0 1 flip" "0 2 flip" "0.1 0 miss" "0.1 0 false"; do
    set -- $args
    .venv/bin/python $E/probe.py "$1" "$2" "$p" "$3"
  done
done > $E/table.txt
