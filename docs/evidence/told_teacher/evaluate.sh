#!/usr/bin/env bash
# Held-out evaluation of the told-teacher study (docs/training.md "A teacher that knows what the actor
# knows"), run from the repository root as `bash docs/evidence/told_teacher/evaluate.sh rld|rlc [to_end]` after
#   lhd train --variant <rld|rlc> --seeds 0-4 --jobs 5 --randomize \
#       --config docs/evidence/told_teacher/lhd_params_told_teacher[_to_end].yaml --out runs/told_teacher[_to_end]_<rld|rlc>
# (to_end: the paired follow-up with the demonstrations to the last step)
# Every seed's final actor: 120 held-out episodes (seed 2,000,000) per condition (lhd report), and the
# slope-error sweep on 15 and 30 deg piles (lhd experiment paper, 20 attempts a cell), the zones built
# from the told slope as on the machine (RLC with the deployment filter, as the nodes run it).
set -euo pipefail
V=${1:?usage: evaluate.sh rld|rlc [to_end]}
N=told_teacher${2:+_$2}
E=docs/evidence/told_teacher
CFG=$E/lhd_params_$N.yaml
NOM=$E/lhd_params_${N}_nominal_eval.yaml
RUNS=runs/${N}_$V
.venv/bin/lhd report $RUNS --held-out nominal,randomized,placement --config $CFG --jobs 2 --json \
    > $E/${N}_${V}_report.json 2> $E/${N}_${V}_report.log
for s in 0 1 2 3 4; do
  .venv/bin/lhd experiment paper --controllers $V --$V $RUNS/seed_$s/final --config $NOM --slopes 15 \
      --materials homogeneous --errors=-15,-10,-5,0,5,10,15 --episodes 20 --jobs 2 --out /tmp/${N}_${V}_seed$s > /dev/null 2>&1
  mkdir -p $E/${N}_${V}_seed$s
  cp /tmp/${N}_${V}_seed$s/table_slope_error.md /tmp/${N}_${V}_seed$s/table_slope_error.csv $E/${N}_${V}_seed$s/
done
