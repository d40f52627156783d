#!/bin/bash
# device: a short ablation (110k steps, 3 arms x 5 seeds) of what makes 15 deg piles fail (not part of the project)
set -u
cd "$(dirname "$0")/.."
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl_eval/*.whl || exit 1
export PYTHONPATH=/tmp/site:$PWD/lhd_loading_ros:$PWD/lhd_sim_node:$PWD/lhd_hw_bridge
export OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 NUMBA_NUM_THREADS=1 CUDA_VISIBLE_DEVICES= MUJOCO_GL=disable
L="python3 -m lhd_loading_ros.cli"
t0=$(date +%s)
for arm in A_dr B_dr_no_slope_error C_nominal; do
  timeout ${TRAIN_S:-470} $L train --variant rld --seeds 0-4 --jobs 5 --steps ${STEPS:-110000} --config runs/stage/abl/$arm.yaml --out /tmp/abl/$arm --no-progress > /tmp/abl_$arm.log 2>&1 &
done
wait
echo "trained $(( $(date +%s) - t0 )) s"; tail -n 2 /tmp/abl/*/seed_0/evals.csv | cut -c1-80
for arm in A_dr B_dr_no_slope_error C_nominal; do for s in 0 1 2 3 4; do
  d=/tmp/abl/$arm/seed_$s; pol=$d/final; [ -f $pol/policy.json ] || pol=$d/best
  mkdir -p $OUT/$arm/seed_$s; cp $d/evals.csv $OUT/$arm/seed_$s/ 2>/dev/null; cp -r $pol $OUT/$arm/seed_$s/ 2>/dev/null
  ($L eval --policy $pol --episodes 40 --seed 2000000 --json 2>/dev/null | tail -1 > $OUT/$arm/seed_$s/eval_nominal.json) &
done; done
wait
echo "total $(( $(date +%s) - t0 )) s"
