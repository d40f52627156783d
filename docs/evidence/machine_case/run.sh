#!/usr/bin/env bash
# Every shipped actor under `lhd eval --stress machine` (placed by hand + from rest + a rough pile: how an attempt on
# the machine goes), 120 held-out episodes (seed 2,000,000), each with its own parameter file where it has one;
# RLC with the deployment filter, as on the machine. From the repository root:
#   bash docs/evidence/machine_case/run.sh [STRESS]      (default machine; writes <actor>_<stress>.json here)
set -euo pipefail
E=docs/evidence/machine_case
S=${1:-machine}
for d in policies/*/; do
  a=$(basename $d)
  cfg=(); [ -f $d/lhd_params.yaml ] && cfg=(--config $d/lhd_params.yaml)
  filt=(); case $a in rlc*) filt=(--deploy-filter);; esac
  .venv/bin/lhd eval --policy $d --episodes 120 --stress $S "${cfg[@]}" "${filt[@]}" --json > $E/${a}_$S.json
  python3 -c "import json,sys; r=json.load(open('$E/${a}_$S.json')); print(f\"$a $S success {r['success_rate']:.3f} by slope {[round(v['success_rate'],2) for v in r['by_slope'].values()]} ASL {r['asl']:.2f} AML {r['aml']:.1f}\")"
done
