#!/usr/bin/env bash
# Held-out evaluation of the zones study (docs/training.md "Where the slope estimate goes"), run from
# the repository root after
#   lhd train --variant rld --seeds 0-4 --jobs 5 --randomize \
#       --config docs/evidence/slope_estimate_zones/lhd_params_zones.yaml --out runs/zones_rld
# Every seed's final actor: 120 held-out episodes (seed 2,000,000) per condition (lhd report), and the
# slope-error sweep on 15 and 30 deg piles (lhd experiment paper, 20 attempts a cell); the same for the
# shipped rld_gains (the same file without the key) beside it.
set -euo pipefail
E=docs/evidence/slope_estimate_zones
CFG=$E/lhd_params_zones.yaml
NOM=$E/lhd_params_zones_nominal_eval.yaml
.venv/bin/lhd report runs/zones_rld --held-out nominal,randomized,placement --config $CFG --jobs 2 --json \
    > $E/zones_rld_report.json 2> $E/zones_rld_report.log
for s in 0 1 2 3 4; do
  .venv/bin/lhd experiment paper --controllers rld --rld runs/zones_rld/seed_$s/final --config $NOM --slopes 15 \
      --materials homogeneous --errors=-15,-10,-5,0,5,10,15 --episodes 20 --jobs 2 --out /tmp/zones_exp_seed$s > /dev/null 2>&1
  mkdir -p $E/zones_rld_seed$s && cp /tmp/zones_exp_seed$s/table_slope_error.md /tmp/zones_exp_seed$s/table_slope_error.csv $E/zones_rld_seed$s/
done
