#!/usr/bin/env bash
# Held-out evaluation of the RLD trained with a quarter of its episodes from rest (docs/evidence/rest_start/README.md),
# from the repository root after
#   lhd train --variant rld --seeds 0-4 --jobs 5 --randomize \
#       --config docs/evidence/rest_start/lhd_params_rest_start.yaml --out runs/rest_start_rld
# Every seed's final actor: 120 held-out episodes (seed 2,000,000) per condition (lhd report: nominal, randomised,
# placed by hand, from rest), and the slope-error sweep on 15 and 30 deg piles (20 attempts a cell, the zones from
# the told slope as on the machine). The shipped rld_told_teacher (the same recipe without starts from rest) is
# evaluated from rest the same way for the comparison.
set -euo pipefail
E=docs/evidence/rest_start
CFG=$E/lhd_params_rest_start.yaml
NOM=$E/lhd_params_rest_start_nominal_eval.yaml
RUNS=runs/rest_start_rld
.venv/bin/lhd report $RUNS --held-out nominal,randomized,placement,rest --config $CFG --jobs 2 --json \
    > $E/rld_report.json 2> $E/rld_report.log
for s in 0 1 2 3 4; do
  .venv/bin/lhd experiment paper --controllers rld --rld $RUNS/seed_$s/final --config $NOM --slopes 15 \
      --materials homogeneous --errors=-15,-10,-5,0,5,10,15 --episodes 20 --jobs 2 --out /tmp/rest_start_seed$s > /dev/null 2>&1
  mkdir -p $E/seed$s
  cp /tmp/rest_start_seed$s/table_slope_error.md /tmp/rest_start_seed$s/table_slope_error.csv $E/seed$s/
done
