#!/usr/bin/env bash
# Held-out evaluation of the cohesion study (docs/training.md "Cohesive material"), run from the
# repository root after:
#   lhd train --variant rld --seeds 0-4 --jobs 5 --randomize \
#       --config docs/evidence/cohesion/lhd_params_cohesion.yaml --out runs/cohesion_rld
# and the actuator-gain study (runs/actuator_gains, docs/evidence/actuator_gains/evaluate.sh), its control:
# the same file with cohesion drawn up to 500 Pa. Both studies' final actors, 120 held-out episodes
# (seed 2,000,000) per condition, under the SAME file (the gains study's: `randomized` draws cohesion up
# to 500 Pa for both), so that every row compares like with like; `cohesive` is 1,500 Pa on every pile.
set -euo pipefail
E=docs/evidence/cohesion
CFG=docs/evidence/actuator_gains/lhd_params_actuator_gains.yaml
.venv/bin/lhd report runs/cohesion_rld --held-out nominal,randomized,placement,slow_drive,slow_hydraulics,cohesive \
  --config $CFG --jobs 2 --json > $E/cohesion_rld_report.json 2> $E/cohesion_rld_report.log
# the control's cohesive row (its other rows: docs/evidence/actuator_gains/actuator_gains_report.json)
.venv/bin/lhd report runs/actuator_gains --held-out cohesive --config $CFG --jobs 2 --json \
  > $E/actuator_gains_rld_cohesive_report.json 2> $E/actuator_gains_rld_cohesive_report.log
# the shipped actors under 1,500 Pa
.venv/bin/lhd eval --policy policies/rld_gains --config policies/rld_gains/lhd_params.yaml --episodes 120 \
  --stress cohesive --json > $E/rld_gains_cohesive.json
.venv/bin/lhd eval --policy policies/rlc_twin_sil_bc --config ${CFG%.yaml}_nominal_eval.yaml --episodes 120 \
  --deploy-filter --stress cohesive --json > $E/rlc_twin_sil_bc_cohesive.json
