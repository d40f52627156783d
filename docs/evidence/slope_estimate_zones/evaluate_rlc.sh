#!/usr/bin/env bash
# The RLC side of evaluate.sh (docs/training.md "Where the slope estimate goes"), after
#   lhd train --variant rlc --seeds 0-4 --jobs 5 --randomize \
#       --config docs/evidence/slope_estimate_zones/lhd_params_zones.yaml --out runs/zones_rlc
# and for the control, the rlc_gains recipe's seeds (runs/actuator_gains_rlc), evaluated the same way
# (RLC with the deployment filter, as the nodes run it).
set -euo pipefail
E=docs/evidence/slope_estimate_zones
for pair in "zones_rlc $E/lhd_params_zones.yaml $E/lhd_params_zones_nominal_eval.yaml" \
            "actuator_gains_rlc docs/evidence/actuator_gains/lhd_params_actuator_gains.yaml docs/evidence/actuator_gains/lhd_params_actuator_gains_nominal_eval.yaml"; do
  set -- $pair
  run=$1; cfg=$2; nom=$3
  [ -d runs/$run ] || continue
  name=$([ $run = zones_rlc ] && echo zones_rlc || echo control_actuator_gains_rlc)
  conds=$([ $run = zones_rlc ] && echo nominal,randomized,placement || echo randomized)
  .venv/bin/lhd report runs/$run --held-out $conds --config $cfg --jobs 2 --json > $E/${name}_report.json 2> $E/${name}_report.log
  for s in 0 1 2 3 4; do
    .venv/bin/lhd experiment paper --controllers rlc --rlc runs/$run/seed_$s/final --config $nom --slopes 15 \
        --materials homogeneous --errors=-15,-10,-5,0,5,10,15 --episodes 20 --jobs 2 --out /tmp/${name}_seed$s > /dev/null 2>&1
    mkdir -p $E/${name}_seed$s && cp /tmp/${name}_seed$s/table_slope_error.md /tmp/${name}_seed$s/table_slope_error.csv $E/${name}_seed$s/
  done
done
