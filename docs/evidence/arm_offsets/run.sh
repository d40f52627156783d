#!/usr/bin/env bash
# The arm's angle sensors off their zero (docs/training.md "The arm's angle sensors"), from the repository root:
#   bash docs/evidence/arm_offsets/run.sh        (about 10 min on 2 cores)
# 1. one sensor at a time, -3..+3 deg (0.5 deg steps near 0), five shipped actors (sweep.jsonl -> sweep.md);
# 2. `lhd eval --stress calibration` (boom and bucket both +-2 deg, every sign pair) for the shipped actors that run
#    on the machine or in the main job, each on its own parameter file, RLC with the deployment filter.
set -euo pipefail
E=docs/evidence/arm_offsets
.venv/bin/python $E/sweep.py run rld_machine,rlc_gains,rld_told_teacher,rld,rlc 120 --offsets=-3,-2,-1,-0.5,0,0.5,1,2,3 > $E/sweep.jsonl
.venv/bin/python $E/sweep.py table $E/sweep.jsonl > $E/sweep.md
for a in rld_machine rld_gains rld_told_teacher rlc_gains rld rlc; do
  cfg=(); [ -f policies/$a/lhd_params.yaml ] && cfg=(--config policies/$a/lhd_params.yaml)
  filt=(); case $a in rlc*) filt=(--deploy-filter);; esac
  .venv/bin/lhd eval --policy policies/$a "${cfg[@]}" "${filt[@]}" --episodes 120 --seed 2000000 --stress calibration \
      > $E/calibration_$a.txt
done
