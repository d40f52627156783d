#!/usr/bin/env bash
# The zones as the end-zone node builds them (a wedge at the told slope and the config's nominal density,
# 1,880 kg/m^3) against the pile's own (its density and rocks in them), for the shipped actors under the
# material stress cases (docs/training.md "The end zone the machine knows"). Run from the repository root:
#   bash docs/evidence/nominal_density_zones/evaluate.sh      (about 3 min on 2 cores)
# 1. lhd eval, 120 held-out episodes (seed 2,000,000), each actor on its own parameter file, RLC with the
#    deployment filter, --zones pile and --zones end-zone-node: <actor>.<condition>.<zones>.json, table.md;
# 2. the slope-error sweep of the machine's RLD on light and dense gravel with the node's zones (lhd experiment
#    paper, 20 attempts a cell): slope_error_<stress>_<zones>/, and (3.) with the node's density set to the
#    material's: slope_error_<stress>_end-zone-node_<density>/.
set -euo pipefail
E=docs/evidence/nominal_density_zones
one() {   # actor condition zones
  local a=$1 c=$2 z=$3 cfg=() filt=() cond=()
  [ -f policies/$a/lhd_params.yaml ] && cfg=(--config policies/$a/lhd_params.yaml)
  case $a in rlc*) filt=(--deploy-filter);; esac
  case $c in nominal) ;; randomized) cond=(--randomize);; *) cond=(--stress $c);; esac
  .venv/bin/lhd eval --policy policies/$a "${cfg[@]}" "${filt[@]}" "${cond[@]}" --zones $z --episodes 120 --json \
      > $E/$a.$c.$z.json
}
export -f one; export E
for a in rld_machine rld_gains rld_told_teacher rlc_gains rld rlc; do
  for c in nominal light dense rocky cohesive machine dense_placement randomized; do
    for z in pile end-zone-node; do echo "$a $c $z"; done
  done
done | xargs -P 2 -L 1 bash -c 'one "$@"' _
.venv/bin/python $E/table.py $E > $E/table.md
for s in light dense; do
  for z in pile end-zone-node; do
    .venv/bin/lhd experiment paper --controllers rld --rld policies/rld_machine --config policies/rld_machine/lhd_params.yaml \
        --slopes 15,30 --materials homogeneous --errors=-15,-10,-5,0,5,10,15 --episodes 20 --jobs 2 --stress $s \
        --zones $z --out /tmp/nd_slope_error_${s}_$z > /dev/null 2>&1
    mkdir -p $E/slope_error_${s}_$z
    cp /tmp/nd_slope_error_${s}_$z/table_slope_error.md /tmp/nd_slope_error_${s}_$z/table_slope_error.csv $E/slope_error_${s}_$z/
  done
done
# 3. the same with the end-zone node's `density` set to the material's (--zones-density: the middle of the stress
#    case's band), as docs/real_machine.md asks an operator to do
for pair in light:1550 dense:2150; do
  s=${pair%%:*}; d=${pair##*:}
  .venv/bin/lhd experiment paper --controllers rld --rld policies/rld_machine --config policies/rld_machine/lhd_params.yaml \
      --slopes 15,30 --materials homogeneous --errors=-15,-10,-5,0,5,10,15 --episodes 20 --jobs 2 --stress $s \
      --zones end-zone-node --zones-density $d --out /tmp/nd_slope_error_${s}_end-zone-node_$d > /dev/null 2>&1
  mkdir -p $E/slope_error_${s}_end-zone-node_$d
  cp /tmp/nd_slope_error_${s}_end-zone-node_$d/table_slope_error.{md,csv} $E/slope_error_${s}_end-zone-node_$d/
done
