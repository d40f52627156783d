#!/usr/bin/env bash
# The machine case (placed by hand, from rest, on a rough face) and from rest alone for every seed's final actor of
# the both-settings recipe trained with a quarter of its episodes from rest (2026-11-30, twentieth session), as
# machine_case_seeds.sh does for the two recipes before it (its first loop, on this recipe's run and evaluation file).
# Run from the repository root after
#   lhd train --variant rld --seeds 0-4 --jobs 5 --randomize \
#       --config docs/evidence/told_high_bound/lhd_params_steep_push_curl_told_high_demos_pile_zones_rest.yaml \
#       --out runs/told_high_demos_pile_zones_rest_rld
# 120 held-out episodes each (seed 2,000,000), 15-30 deg piles, on the file's own nominal evaluation file
# (rest_start_share is in the config hash).
set -euo pipefail
RUNS=told_high_demos_pile_zones_rest_rld EXTRA=0 \
CFG=docs/evidence/told_high_bound/lhd_params_steep_push_curl_told_high_demos_pile_zones_rest_nominal_eval.yaml \
  exec bash docs/evidence/told_high_bound/machine_case_seeds.sh
