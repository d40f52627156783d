#!/usr/bin/env bash
# Held-out evaluation of issue 14's whole study on the shipped parameter file (docs/evidence/paper_study/README.md),
# from the repository root after
#   lhd sweep docs/evidence/paper_study/study.yaml --jobs 10
# 1. Every seed's final actor, both variants: 120 held-out episodes (seed 2,000,000) per condition (lhd report:
#    nominal, placed by hand, from rest, randomised), with the training curves.
# 2. The median seed of each variant as lhd ship picks it, into /tmp/paper_study_ship/<variant> (its card and table).
# 3. The shipped main-job actors (policies/rld, policies/rlc, trained before the rear differential) under the same
#    conditions, for the comparison.
# 4. lhd experiment paper with the two median actors against the heuristic, 20 attempts a cell, and the slope-error
#    table (the zones from the told slope, as on the machine).
set -euo pipefail
E=docs/evidence/paper_study
RUNS=runs/paper_study
COND=nominal,placement,rest,randomized
for v in rld rlc; do
  .venv/bin/lhd report $RUNS/$v --held-out $COND --jobs 2 --json --plot $E/${v}_curves.png \
      > $E/${v}_report.json 2> $E/${v}_report.log
  .venv/bin/lhd ship --variant $v $RUNS/$v --out /tmp/paper_study_ship/$v > $E/${v}_ship.log 2>&1
  cp /tmp/paper_study_ship/$v/README.md $E/${v}_median_card.md
  for c in nominal placement rest randomized; do
    case $c in nominal) flag="";; randomized) flag="--randomize";; *) flag="--stress $c";; esac
    filt=""; [ $v = rlc ] && filt=--deploy-filter
    .venv/bin/lhd eval --policy policies/$v --episodes 120 $flag $filt --json > $E/shipped_${v}_$c.json 2>/dev/null
  done
done
rld=$(cat /tmp/paper_study_ship/rld/policy.json | python3 -c "import json,sys; print(json.load(sys.stdin).get('seed'))")
.venv/bin/lhd experiment paper --rld /tmp/paper_study_ship/rld --rlc /tmp/paper_study_ship/rlc \
    --controllers rld,rlc,tampier --episodes 20 --jobs 2 --out $E/experiment_paper > $E/experiment_paper.log 2>&1
echo "evaluated; the median RLD is seed $rld"
