#!/usr/bin/env bash
# What an untrained actor scores (docs/results.md "What success means on steep piles"; a new-user review,
# 2026-12-01): five RLD and five RLC actors exported after 600 environment steps, before the first update
# (training.learning_starts 1,000: the network is its random initialisation), each evaluated as the shipped
# actors are (lhd eval, 120 held-out episodes, seed 2,000,000, the default parameter file, 15-30 deg piles).
# Run from the repository root: bash docs/evidence/untrained_actors/run.sh > docs/evidence/untrained_actors/untrained.txt
set -euo pipefail
for v in rld rlc; do
  for s in 0 1 2 3 4; do
    d=/tmp/untrained_${v}_$s
    rm -rf "$d"
    .venv/bin/lhd train --variant $v --seed $s --steps 600 --out "$d" --no-progress > /dev/null 2>&1
    echo "== untrained $v, seed $s"
    .venv/bin/lhd eval --policy "$d/final" --episodes 120 2>&1 | grep -E "^ +(all|15 deg|20 deg|25 deg|30 deg|episodes) "
    rm -rf "$d"
  done
done
