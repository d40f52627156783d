#!/usr/bin/env bash
# Held-out evaluation of the told-teacher study (docs/training.md "A teacher that knows what the actor
# knows"), run from the repository root after
#   lhd train --variant rld --seeds 0-4 --jobs 5 --randomize \
#       --config docs/evidence/told_teacher/lhd_params_told_teacher.yaml --out runs/told_teacher_rld
# Every seed's final actor: 120 held-out episodes (seed 2,000,000) per condition (lhd report), and the
# slope-error sweep on 15 and 30 deg piles (lhd experiment paper, 20 attempts a cell), the zones built
# from the told slope as on the machine.
set -euo pipefail
E=docs/evidence/told_teacher
CFG=$E/lhd_params_told_teacher.yaml
NOM=$E/lhd_params_told_teacher_nominal_eval.yaml
RUNS=${RUNS:-runs/told_teacher_rld}
.venv/bin/lhd report $RUNS --held-out nominal,randomized,placement --config $CFG --jobs 2 --json \
    > $E/told_teacher_rld_report.json 2> $E/told_teacher_rld_report.log
for s in 0 1 2 3 4; do
  .venv/bin/lhd experiment paper --controllers rld --rld $RUNS/seed_$s/final --config $NOM --slopes 15 \
      --materials homogeneous --errors=-15,-10,-5,0,5,10,15 --episodes 20 --jobs 2 --out /tmp/told_exp_seed$s > /dev/null 2>&1
  mkdir -p $E/told_teacher_rld_seed$s && cp /tmp/told_exp_seed$s/table_slope_error.md /tmp/told_exp_seed$s/table_slope_error.csv $E/told_teacher_rld_seed$s/
done
