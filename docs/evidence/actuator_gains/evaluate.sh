#!/usr/bin/env bash
# Held-out evaluation of the actuator-gain study (docs/training.md "Actuator gains"), run from the
# repository root after:
#   lhd train --variant rld --seeds 0-4 --jobs 5 --randomize \
#       --config docs/evidence/actuator_gains/lhd_params_actuator_gains.yaml --out runs/actuator_gains
#   lhd train --variant rld --seeds 0-4 --jobs 5 --randomize \
#       --config docs/evidence/wide_demo_twin_sil_bc3/lhd_params_wide_demo_twin_sil_bc3.yaml --out runs/sil_bc3_rld_control
# Every run's final actor, 120 held-out episodes (seed 2,000,000) per condition, under the gains
# file (its `randomized` draws the gains too; the control's actors see the same piles and machines).
# lhd eval reads the section's enabled flag: the shipped actor is run under the nominal-eval copy (enabled 0;
# --randomize and --stress set the conditions).
set -euo pipefail
E=docs/evidence/actuator_gains
CFG=$E/lhd_params_actuator_gains.yaml
CONDS=nominal,randomized,placement,slow_drive,slow_hydraulics
for run in actuator_gains sil_bc3_rld_control; do
  if [ -d runs/$run ]; then
    .venv/bin/lhd report runs/$run --held-out $CONDS --config $CFG --jobs 2 --json > $E/${run}_report.json 2> $E/${run}_report.log
  fi
done
# the shipped RLD (rld_twin: the same physics and observation scaling as the file above)
for c in nominal randomized slow_drive slow_hydraulics placement; do
  if [ $c = randomized ]; then flag=--randomize; elif [ $c = nominal ]; then flag=; else flag="--stress $c"; fi
  .venv/bin/lhd eval --policy policies/rld_twin --config ${CFG%.yaml}_nominal_eval.yaml --episodes 120 $flag --json > $E/rld_twin_$c.json
done
