#!/bin/bash
# The machine recipe's five seeds (runs/machine_rld, from `bash docs/evidence/machine_recipe/evaluate.sh`'s training
# command), every departure of its file drawn at once, with the attempts the nodes refuse (a told slope outside
# 10-35 deg) counted as refused, as `lhd report --held-out` does since 2026-11-29: 120 held-out episodes (seed
# 2,000,000) a seed. About 15 s on 2 cores.
set -e
cd "$(dirname "$0")/../../.."
RUNS=${RUNS:-runs/machine_rld}
.venv/bin/lhd report $RUNS --held-out randomized --config docs/evidence/machine_recipe/lhd_params_machine.yaml \
    --jobs 2 --json > docs/evidence/refused_slopes/machine_rld_seeds_randomized.json
