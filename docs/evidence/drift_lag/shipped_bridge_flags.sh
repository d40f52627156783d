#!/usr/bin/env bash
# Shipped actors from rest and placed as on the machine, with the simulator's drift window and with the bridge's
# (the observed flag over a control period ending 0-140 ms before each observation: --stress rest_bridge /
# machine_bridge). 120 held-out episodes per cell (seed 2,000,000), each actor on its own parameter file, RLC with
# its deployment filter. Run from the repository root:
#   bash docs/evidence/drift_lag/shipped_bridge_flags.sh > docs/evidence/drift_lag/shipped_bridge_flags.txt
set -euo pipefail
ACTORS=${ACTORS:-"rld rlc rld_machine rlc_gains rld_told_high rld_told_high_rest rld_twin"}
CASES=${CASES:-"rest rest_bridge machine machine_bridge"}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
printf '%-20s %-15s %8s %8s %s\n' actor stress success AML "success / AML by slope"
for a in $ACTORS; do
  extra=()
  case $a in rlc*) extra=(--deploy-filter) ;; esac
  cfg=()
  [ -f "policies/$a/lhd_params.yaml" ] && cfg=(--config "policies/$a/lhd_params.yaml")
  for s in $CASES; do
    .venv/bin/lhd eval --policy "policies/$a" "${cfg[@]}" "${extra[@]}" --stress "$s" --episodes 120 \
        --seed 2000000 --json > "$tmp/r.json"
    python3 - "$a" "$s" "$tmp/r.json" <<'PY'
import json, sys
a, s, f = sys.argv[1:]
d = json.load(open(f))
by = " ".join(f"{k}:{v['success_rate']:.2f}/{v['aml']:.1f}" for k, v in d["by_slope"].items())
print(f"{a:<20} {s:<15} {d['success_rate']:8.3f} {d['aml']:8.1f} {by}")
PY
  done
done
