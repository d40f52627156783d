#!/usr/bin/env bash
# The machine recipe trained with the arm's angle sensors off their zero (randomization.arm_offset_max_deg: 2.5)
# against the same recipe without them (the shipped rld_machine's five seeds, runs/machine_rld), both evaluated the
# same way (docs/training.md "The arm's angle sensors"). After
#   lhd train --variant rld --seeds 0-4 --jobs 5 --randomize \
#       --config docs/evidence/arm_offsets/lhd_params_machine_arm.yaml --out runs/machine_arm_rld
# and the machine recipe's runs/machine_rld, from the repository root (about 12 min on 2 cores):
#   bash docs/evidence/arm_offsets/evaluate_training.sh
# Every seed's final actor, 120 held-out episodes (seed 2,000,000) a condition:
#   1. lhd report: nominal, randomised (this file's ranges, the arm offsets among them, for both runs), placed by
#      hand, the machine case and --stress calibration;
#   2. the machine case with the arm 2 deg off on top (machine_case/combined.py), and with a slope 3 deg high / low;
#   3. the slope-error sweep on 15 deg piles (lhd experiment paper, 20 attempts a cell), zones from the told slope.
set -euo pipefail
E=docs/evidence/arm_offsets
M=docs/evidence/machine_recipe
NOM=$M/lhd_params_machine_nominal_eval.yaml    # the section off: the same config hash for both runs
for run in machine_arm_rld machine_rld; do
  .venv/bin/lhd report runs/$run --held-out nominal,randomized,placement,machine,calibration \
      --config $E/lhd_params_machine_arm.yaml --jobs 2 --json > $E/${run}_report.json 2> $E/${run}_report.log
  .venv/bin/python docs/evidence/machine_case/combined.py --config $NOM --cases none,calibration,slope_high_3,slope_low_3 \
      runs/$run/seed_{0,1,2,3,4}/final > $E/${run}_combined.txt
  for s in 0 1 2 3 4; do
    .venv/bin/lhd experiment paper --controllers rld --rld runs/$run/seed_$s/final --config $NOM --slopes 15 \
        --materials homogeneous --errors=-15,-10,-5,0,5,10,15 --episodes 20 --jobs 2 --out /tmp/arm_${run}_seed$s \
        > /dev/null 2>&1
    mkdir -p $E/${run}_seed$s
    cp /tmp/arm_${run}_seed$s/table_slope_error.md /tmp/arm_${run}_seed$s/table_slope_error.csv $E/${run}_seed$s/
  done
done
