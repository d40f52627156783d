#!/bin/bash
# The two shipped actors of run seed 2 (the main job's `rld`; `rlc_gains`), whose first ~114 training piles were
# held-out seeds 2,000,006..2,000,119, on the held-out seed and on 2,500,000 (no run's training seeds come near it).
set -e
cd "$(dirname "$0")/../../.."
for seed in 2000000 2500000; do
  echo "== policies/rld, seed $seed"; .venv/bin/lhd eval --policy policies/rld --seed $seed | sed -n 3p
  echo "== policies/rlc_gains (deployment filter), seed $seed"
  .venv/bin/lhd eval --policy policies/rlc_gains --config policies/rlc_gains/lhd_params.yaml --deploy-filter --seed $seed | sed -n 3p
done
