#!/usr/bin/env bash
# The machine case (placed by hand, from rest, on a rough face) and from rest alone for every seed's final actor of
# the both-settings recipe trained with a quarter of its episodes from rest (2026-11-30, twentieth session), as
# machine_case_seeds.sh does for the two recipes before it. Run from the repository root after
#   lhd train --variant rld --seeds 0-4 --jobs 5 --randomize \
#       --config docs/evidence/told_high_bound/lhd_params_steep_push_curl_told_high_demos_pile_zones_rest.yaml \
#       --out runs/told_high_demos_pile_zones_rest_rld
# 120 held-out episodes each (seed 2,000,000), 15-30 deg piles, on the file's own nominal evaluation file
# (rest_start_share is in the config hash).
set -euo pipefail
CFG=docs/evidence/told_high_bound/lhd_params_steep_push_curl_told_high_demos_pile_zones_rest_nominal_eval.yaml
run=told_high_demos_pile_zones_rest_rld
for st in machine rest; do
  for s in 0 1 2 3 4; do
    echo "== $run seed $s, --stress $st"
    .venv/bin/lhd eval --policy runs/$run/seed_$s/final --config $CFG --stress $st --episodes 120 \
        | grep -E "^ +(all|15 deg|20 deg)|^failures"
  done
done
