#!/usr/bin/env bash
# Held-out evaluation of the machine recipe for RLC (docs/training.md "The machine recipe"), run from the repository
# root as `bash docs/evidence/machine_recipe/evaluate_rlc.sh` after
#   lhd train --variant rlc --seeds 0-4 --jobs 5 --randomize \
#       --config docs/evidence/machine_recipe/lhd_params_machine.yaml --out runs/machine_rlc
# As evaluate.sh for RLD, RLC with the deployment filter (as the nodes run it): lhd report (nominal, randomised,
# placed by hand, the machine case), the machine case with one more departure, the slope-error sweep.
set -euo pipefail
E=docs/evidence/machine_recipe
CFG=$E/lhd_params_machine.yaml
NOM=$E/lhd_params_machine_nominal_eval.yaml
RUNS=${RUNS:-runs/machine_rlc}
SEEDS=${SEEDS:-0 1 2 3 4}         # the seeds of combined.py and the sweeps (all five finished in the ninth session)
FINALS=(); for s in $SEEDS; do FINALS+=($RUNS/seed_$s/final); done
# lhd report takes the parent folder, every seed in it: one group, the seeds' mean +- sd
.venv/bin/lhd report $RUNS --held-out nominal,randomized,placement,machine --config $CFG --jobs 2 --json \
    > $E/machine_rlc_report.json 2> $E/machine_rlc_report.log
.venv/bin/python docs/evidence/machine_case/combined.py --config $NOM "${FINALS[@]}" > $E/combined_rlc.txt
for s in $SEEDS; do
  .venv/bin/lhd experiment paper --controllers rlc --rlc $RUNS/seed_$s/final --config $NOM --slopes 15 \
      --materials homogeneous --errors=-15,-10,-5,0,5,10,15 --episodes 20 --jobs 2 --out /tmp/machine_rlc_seed$s > /dev/null 2>&1
  mkdir -p $E/machine_rlc_seed$s
  cp /tmp/machine_rlc_seed$s/table_slope_error.md /tmp/machine_rlc_seed$s/table_slope_error.csv $E/machine_rlc_seed$s/
done
