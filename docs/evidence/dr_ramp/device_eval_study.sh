#!/bin/bash
# device: held-out report and the paper's experiment for a staged study (not part of the project).
# usage: STUDY=runs/stage/<name> VARIANT=rld bash .whl/eval_study.sh
set -u
cd "$(dirname "$0")/.."
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl_eval/*.whl || exit 1
export PYTHONPATH=/tmp/site:$PWD/lhd_loading_ros:$PWD/lhd_sim_node:$PWD/lhd_hw_bridge
export OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 NUMBA_NUM_THREADS=1 CUDA_VISIBLE_DEVICES=
L="python3 -m lhd_loading_ros.cli"
nproc; lscpu | grep "Model name"
t0=$(date +%s)
$L report $STUDY --held-out ${CONDS:-nominal,randomized,placement,light,dense,sensors,delay} --jobs 16 --json > $OUT/report.json 2> $OUT/report.err
echo "report rc $? $(( $(date +%s) - t0 )) s"; tail -5 $OUT/report.err
for d in $STUDY/seed_*; do
  s=$(basename $d)
  t1=$(date +%s)
  $L experiment paper --controllers $VARIANT --$VARIANT $d/final --episodes 20 --jobs 16 --out /tmp/exp/$s > /tmp/exp_$s.log 2>&1
  echo "experiment $s rc $? $(( $(date +%s) - t1 )) s"; tail -2 /tmp/exp_$s.log
done
cd /tmp && tar czf $OUT/experiments.tgz exp && ls -la $OUT
echo "total $(( $(date +%s) - t0 )) s"
