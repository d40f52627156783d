#!/usr/bin/env bash
# Held-out evaluation of the RLC without actuator gains (docs/evidence/rlc_no_gains/README.md), from the repository
# root after
#   lhd train --variant rlc --seeds 0-4 --jobs 5 --randomize \
#       --config docs/evidence/rlc_no_gains/lhd_params_rlc_no_gains.yaml --out runs/rlc_no_gains
# Every seed's final actor: 120 held-out episodes (seed 2,000,000) per condition (lhd report, with the deployment
# filter), the slope-error sweep on 15 and 30 deg piles (20 attempts a cell, the zones from the told slope as on the
# machine) and the stress cases slow_drive / slow_hydraulics (what the gains were drawn for) and rest.
set -euo pipefail
E=docs/evidence/rlc_no_gains
CFG=$E/lhd_params_rlc_no_gains.yaml
NOM=$E/lhd_params_rlc_no_gains_nominal_eval.yaml
RUNS=runs/rlc_no_gains
.venv/bin/lhd report $RUNS --held-out nominal,randomized,placement --config $CFG --jobs 2 --json \
    > $E/rlc_report.json 2> $E/rlc_report.log
for s in 0 1 2 3 4; do
  .venv/bin/lhd experiment paper --controllers rlc --rlc $RUNS/seed_$s/final --config $NOM --slopes 15 \
      --materials homogeneous --errors=-15,-10,-5,0,5,10,15 --episodes 20 --jobs 2 --out /tmp/rlc_no_gains_seed$s > /dev/null 2>&1
  mkdir -p $E/seed$s
  cp /tmp/rlc_no_gains_seed$s/table_slope_error.md /tmp/rlc_no_gains_seed$s/table_slope_error.csv $E/seed$s/
  for st in slow_drive slow_hydraulics rest; do
    .venv/bin/lhd experiment paper --controllers rlc --rlc $RUNS/seed_$s/final --config $NOM --errors=0 --episodes 10 \
        --jobs 2 --stress $st --out /tmp/rlc_no_gains_seed${s}_$st > /dev/null 2>&1
    cp /tmp/rlc_no_gains_seed${s}_$st/table_controllers.md $E/seed$s/table_$st.md
  done
done
