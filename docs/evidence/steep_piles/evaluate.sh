#!/usr/bin/env bash
# Held-out evaluation of the 10-40 deg study (docs/training.md "Piles of 10-40 deg"), run from the repository
# root as `bash docs/evidence/steep_piles/evaluate.sh` after
#   lhd train --variant rld --seeds 0-4 --jobs 5 --randomize \
#       --config docs/evidence/steep_piles/lhd_params_steep.yaml --out runs/steep_rld
# Every seed's final actor (no best checkpoint, no best seed):
#  - lhd report: 120 held-out episodes (seed 2,000,000) per condition, the 5 seeds' mean +- sd and IQM;
#    dense and light gravel and rocky piles are conditions of the same command;
#  - lhd experiment paper per seed, nominal conditions: table (a) every slope of 10-40 deg, both materials,
#    20 attempts a cell, and table (b) the slope-error sweep on 15 and 30 deg piles (zones built from the told
#    slope, as on the machine).
set -euo pipefail
E=docs/evidence/steep_piles
CFG=$E/lhd_params_steep.yaml
NOM=$E/lhd_params_steep_nominal_eval.yaml
RUNS=runs/steep_rld
.venv/bin/lhd report $RUNS --held-out nominal,randomized,placement,sensors,delay,light,dense,rocky --config $CFG \
    --jobs 2 --json > $E/steep_rld_report.json 2> $E/steep_rld_report.log
for s in 0 1 2 3 4; do
  .venv/bin/lhd experiment paper --controllers rld --rld $RUNS/seed_$s/final --config $NOM \
      --slopes 10,15,20,25,30,35,40 --errors=-15,-10,-5,0,5,10,15 --episodes 20 --jobs 2 \
      --out /tmp/steep_rld_seed$s > /dev/null 2>&1
  mkdir -p $E/steep_rld_seed$s
  cp /tmp/steep_rld_seed$s/table_controllers.md /tmp/steep_rld_seed$s/table_controllers.csv \
     /tmp/steep_rld_seed$s/table_slope_error.md /tmp/steep_rld_seed$s/table_slope_error.csv $E/steep_rld_seed$s/
done
