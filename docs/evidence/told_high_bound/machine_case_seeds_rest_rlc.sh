#!/usr/bin/env bash
# The same recipe trained as RLC (2026-11-30, twenty-second session): every seed's final actor, with the deployment
# filter as the nodes run it, from rest and as on the machine (placed by hand, from rest, on a rough face), each with
# the simulator's drift window and with the bridge's (rest_bridge, machine_bridge). Run from the repository root after
#   lhd train --variant rlc --seeds 0-4 --jobs 5 --randomize \
#       --config docs/evidence/told_high_bound/lhd_params_steep_push_curl_told_high_demos_pile_zones_rest.yaml \
#       --out runs/told_high_demos_pile_zones_rest_rlc
# 120 held-out episodes each (seed 2,000,000), 15-30 deg piles, on the file's own nominal evaluation file:
#   bash docs/evidence/told_high_bound/machine_case_seeds_rest_rlc.sh > docs/evidence/told_high_bound/machine_case_seeds_rest_rlc.txt
set -euo pipefail
STRESS="rest machine rest_bridge machine_bridge" RUNS=told_high_demos_pile_zones_rest_rlc EXTRA=0 \
EVAL_ARGS=--deploy-filter \
CFG=docs/evidence/told_high_bound/lhd_params_steep_push_curl_told_high_demos_pile_zones_rest_nominal_eval.yaml \
  exec bash docs/evidence/told_high_bound/machine_case_seeds.sh
