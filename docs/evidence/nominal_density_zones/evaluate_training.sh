#!/usr/bin/env bash
# The machine recipe trained with the end-zone node's zones (randomization.zones_at_nominal_density: 1) against
# the same recipe without them (the shipped rld_machine's five seeds), both evaluated with the node's zones
# (--zones end-zone-node), as on the machine (docs/training.md "The end zone the machine knows"). After
#   lhd train --variant rld --seeds 0-4 --jobs 5 --randomize \
#       --config docs/evidence/nominal_density_zones/lhd_params_machine_nd.yaml --out runs/machine_nd_rld
# and the machine recipe's runs/machine_rld, from the repository root (about 7 min on 2 cores):
#   bash docs/evidence/nominal_density_zones/evaluate_training.sh
set -euo pipefail
E=docs/evidence/nominal_density_zones
M=docs/evidence/machine_recipe
for run in machine_nd_rld machine_rld; do
  case $run in
    machine_nd_rld) CFG=$E/lhd_params_machine_nd.yaml; NOM=$E/lhd_params_machine_nd_nominal_eval.yaml;;
    machine_rld) CFG=$M/lhd_params_machine.yaml; NOM=$M/lhd_params_machine_nominal_eval.yaml;;
  esac
  .venv/bin/lhd report runs/$run --held-out nominal,randomized,placement,machine,light,dense --config $CFG \
      --zones end-zone-node --jobs 2 --json > $E/${run}_node_report.json 2> $E/${run}_node_report.log
  .venv/bin/python docs/evidence/machine_case/combined.py --config $NOM --zones end-zone-node \
      --cases none,light,dense,slow_drive,cohesive,slope_high_3,slope_low_3 runs/$run/seed_{0,1,2,3,4}/final \
      > $E/${run}_combined_node.txt
  for s in 0 1 2 3 4; do
    for stress in nominal light; do
      extra=(); [ $stress = nominal ] || extra=(--stress $stress)
      .venv/bin/lhd experiment paper --controllers rld --rld runs/$run/seed_$s/final --config $NOM --slopes 15 \
          --materials homogeneous --errors=-15,-10,-5,0,5,10,15 --episodes 20 --jobs 2 "${extra[@]}" \
          --zones end-zone-node --out /tmp/nd_${run}_seed${s}_$stress > /dev/null 2>&1
      mkdir -p $E/${run}_seed${s}_$stress
      cp /tmp/nd_${run}_seed${s}_$stress/table_slope_error.md /tmp/nd_${run}_seed${s}_$stress/table_slope_error.csv \
          $E/${run}_seed${s}_$stress/
    done
  done
done
