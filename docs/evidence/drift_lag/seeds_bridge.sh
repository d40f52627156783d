#!/usr/bin/env bash
# Every seed's final actor of the both-settings recipe with rest starts, trained with the simulator's drift window
# (runs/told_high_demos_pile_zones_rest_rld, 2026-11-30, twentieth session) and with the bridge's
# (runs/told_high_demos_pile_zones_rest_driftlag_rld, randomization.drift_flag_lag_max_s 0.14, twenty-first
# session), from rest and as on the machine with the bridge's drift flags (--stress rest_bridge, machine_bridge);
# the new recipe's seeds also with the simulator's flags (rest, machine), which the twentieth session measured for
# the old one (docs/evidence/told_high_bound/machine_case_seeds_rest.txt). 120 held-out episodes each (seed
# 2,000,000), 15-30 deg piles, each recipe on its own nominal evaluation file. Run from the repository root:
#   bash docs/evidence/drift_lag/seeds_bridge.sh > docs/evidence/drift_lag/seeds_bridge.txt
set -euo pipefail
E=docs/evidence/told_high_bound
S=docs/evidence/told_high_bound/machine_case_seeds.sh
STRESS="rest_bridge machine_bridge" RUNS=told_high_demos_pile_zones_rest_rld EXTRA=0 \
  CFG=$E/lhd_params_steep_push_curl_told_high_demos_pile_zones_rest_nominal_eval.yaml bash $S
STRESS="rest_bridge machine_bridge rest machine" RUNS=told_high_demos_pile_zones_rest_driftlag_rld EXTRA=0 \
  CFG=$E/lhd_params_steep_push_curl_told_high_demos_pile_zones_rest_driftlag_nominal_eval.yaml bash $S
