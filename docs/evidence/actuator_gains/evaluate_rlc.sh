#!/usr/bin/env bash
# Held-out evaluation of the RLC actuator-gain study (docs/training.md "Actuator gains: RLC"), run from
# the repository root after:
#   lhd train --variant rlc --seeds 0-4 --jobs 5 --randomize \
#       --config docs/evidence/actuator_gains/lhd_params_actuator_gains.yaml --out runs/actuator_gains_rlc
# Every run's final actor, 120 held-out episodes (seed 2,000,000) per condition, with the deployment
# filter (lhd report runs RLC with it, as the machine does), under the gains file; then the shipped RLC
# trained without gains (rlc_twin_sil_bc: the same physics and observation scaling) under the same
# conditions, as the control (its cohesive row: docs/evidence/cohesion/evaluate.sh).
set -euo pipefail
E=docs/evidence/actuator_gains
CFG=$E/lhd_params_actuator_gains.yaml
CONDS=nominal,randomized,placement,slow_drive,slow_hydraulics,cohesive
if [ -d runs/actuator_gains_rlc ]; then
  .venv/bin/lhd report runs/actuator_gains_rlc --held-out $CONDS --config $CFG --jobs 2 --json \
    > $E/actuator_gains_rlc_report.json 2> $E/actuator_gains_rlc_report.log
fi
for c in nominal randomized slow_drive slow_hydraulics placement; do
  if [ $c = randomized ]; then flag=--randomize; elif [ $c = nominal ]; then flag=; else flag="--stress $c"; fi
  .venv/bin/lhd eval --policy policies/rlc_twin_sil_bc --config ${CFG%.yaml}_nominal_eval.yaml --episodes 120 \
    --deploy-filter $flag --json > $E/rlc_twin_sil_bc_$c.json
done
