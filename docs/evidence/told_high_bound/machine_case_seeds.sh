#!/usr/bin/env bash
# The machine case (placed by hand, from rest, on a rough face: how an attempt on the machine goes) for every
# seed's final actor of the two told-high recipes, not only the shipped seed (2026-11-30, nineteenth session); from
# rest alone for every seed of both; placed by hand and on a rough face alone for the new recipe's seeds 0 and 2.
# Run from the repository root after training both:
#   runs/told_high_demos_rld            (lhd_params_steep_push_curl_told_high_demos.yaml; shipped: seed 4)
#   runs/told_high_demos_pile_zones_rld (lhd_params_steep_push_curl_told_high_demos_pile_zones.yaml)
# 120 held-out episodes each (seed 2,000,000), 15-30 deg piles; the nominal evaluation file both ship with.
set -euo pipefail
# machine_case_seeds_rest.sh runs the first loop alone for another recipe (RUNS, CFG and EXTRA=0 from it), and
# docs/evidence/drift_lag/seeds_bridge.sh with other stress cases (STRESS); EVAL_ARGS=--deploy-filter for RLC runs
# (as the nodes run them).
CFG=${CFG:-docs/evidence/told_high_bound/lhd_params_steep_push_curl_nominal_eval.yaml}
RUNS=${RUNS:-"told_high_demos_rld told_high_demos_pile_zones_rld"}
for st in ${STRESS:-machine rest}; do
  for run in $RUNS; do
    for s in 0 1 2 3 4; do
      echo "== $run seed $s, --stress $st"
      .venv/bin/lhd eval --policy runs/$run/seed_$s/final --config $CFG --stress $st --episodes 120 ${EVAL_ARGS:-} \
          | grep -E "^ +(all|15 deg|20 deg)|^failures"
    done
  done
done
[ "${EXTRA:-1}" = 1 ] || exit 0
for s in 0 2; do
  for st in placement rough; do
    echo "== told_high_demos_pile_zones_rld seed $s, --stress $st"
    .venv/bin/lhd eval --policy runs/told_high_demos_pile_zones_rld/seed_$s/final --config $CFG --stress $st \
        --episodes 120 | grep -E "^ +(all|15 deg)|^failures"
  done
done
