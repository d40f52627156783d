#!/bin/bash
# The config-only cases through the project's own CLI (`lhd eval`), one process at a time, same seed
# (default 2,000,000) and 40 episodes as robust_eval.py; RLC with --deploy-filter (as on the machine).
cd /work/main
for actor in rld rlc; do
  if [ $actor = rld ]; then pol=policies/rld_twin; flt=""; else pol=policies/rlc_twin_sil_bc; flt="--deploy-filter"; fi
  for case in nominal hyd_force_m25 wheel_torque_m20 floor_slippery_045 floor_grippy_110 pile_cohesion_1500 pile_phi_42_45 machine_heavy_p15kg pile_wide_080_refused pile_wide_080; do
    out=/tmp/robust/json/lhdeval_${actor}_${case}
    .venv/bin/lhd eval --policy $pol --config /tmp/robust/configs/${actor}_${case}.yaml --episodes 40 --json $flt > $out.json 2> $out.err
    echo "$actor $case rc=$? $(python3 -c "import json,sys
try:
  d=json.load(open('$out.json')); print('succ',d['success_rate'],'aml',round(d['aml'],2),d['failures'])
except Exception as e: print('no json:', open('$out.err').read().strip()[:600])")"
  done
done
