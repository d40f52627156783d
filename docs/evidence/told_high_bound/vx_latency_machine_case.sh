#!/usr/bin/env bash
# The machine case (lhd eval --stress machine: placed by hand, from rest, rough face, the camera's noise and dropouts,
# 100 ms actuator dead time) with the camera's speed 1-3 control steps old (the stress case takes
# randomization.vx_delay_steps_max; trained with 0-1), for rld_told_high_rest and rld_told_high (2026-11-30, twentieth
# session): the digital twin on this 2-core machine delivered odometry 67-320 ms late (median per attempt), and there
# rld_told_high_rest failed 15 deg piles that rld_told_high loaded. 120 held-out episodes each, each actor's own file
# with only that key changed (the randomization section is off and not in the config hash). Run from the repository root.
set -euo pipefail
for p in rld_told_high_rest rld_told_high; do
  for k in 1 2 3; do
    f=$(mktemp --suffix=.yaml)
    sed "s/^  vx_delay_steps_max: 1 /  vx_delay_steps_max: $k /" policies/$p/lhd_params.yaml > $f
    grep -q "^  vx_delay_steps_max: $k " $f
    echo "== $p, machine case, v_x ${k} steps old"
    .venv/bin/lhd eval --policy policies/$p --config $f --stress machine --episodes 120 | grep -E "^ +(all|15 deg|20 deg|25 deg|30 deg)|^failures"
    rm -f $f
  done
done
