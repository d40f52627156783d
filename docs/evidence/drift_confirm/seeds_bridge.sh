#!/usr/bin/env bash
# Every seed's final actor of the drift-confirm recipe (runs/drift_confirm3_rld: the bridge's drift window recipe of
# docs/evidence/told_high_bound/lhd_params_steep_push_curl_told_high_demos_pile_zones_rest_driftlag.yaml with
# training.demo_drift_confirm 3; 2026-12-01, twenty-fourth session), from rest and as on the machine, with the
# bridge's drift flags (--stress rest_bridge, machine_bridge) and the simulator's (rest, machine), as
# docs/evidence/drift_lag/seeds_bridge.sh measured the two recipes before it. 120 held-out episodes each (seed
# 2,000,000), 15-30 deg piles, on the recipe's nominal evaluation file. Run from the repository root after
#   lhd train --variant rld --seeds 0-4 --jobs 5 --randomize \
#       --config docs/evidence/drift_confirm/lhd_params_drift_confirm3.yaml --out runs/drift_confirm3_rld
#   bash docs/evidence/drift_confirm/seeds_bridge.sh > docs/evidence/drift_confirm/seeds_bridge.txt
# The same recipe as RLC (2026-12-01, twenty-fifth session; runs/drift_confirm3_rlc), with the deployment filter as the
# nodes run it:
#   bash docs/evidence/drift_confirm/seeds_bridge.sh rlc > docs/evidence/drift_confirm/seeds_bridge_rlc.txt
# and with the level push (runs/drift_confirm3_level_push_rlc):
#   bash docs/evidence/drift_confirm/seeds_bridge.sh level_push_rlc > docs/evidence/drift_confirm/seeds_bridge_level_push_rlc.txt
set -euo pipefail
V=${1:-rld}
case $V in rld) ARGS= ;; rlc|level_push_rlc) ARGS=--deploy-filter ;;
  *) echo "usage: seeds_bridge.sh [rld|rlc|level_push_rlc]" >&2; exit 2 ;; esac
STRESS="rest_bridge machine_bridge rest machine" RUNS=drift_confirm3_$V EXTRA=0 EVAL_ARGS=$ARGS \
  CFG=docs/evidence/drift_confirm/lhd_params_drift_confirm3_nominal_eval.yaml \
  exec bash docs/evidence/told_high_bound/machine_case_seeds.sh
