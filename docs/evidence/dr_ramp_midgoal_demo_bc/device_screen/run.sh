#!/bin/bash
# 15 training runs of 300,000 steps, one core each; results tarred into $OUT before the limit
set -u
T0=$(date +%s)
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 1
export PYTHONPATH=/tmp/site:$PWD/lhd_loading_ros:$PWD/lhd_sim_node PYTHONUNBUFFERED=1
nproc; python3 -c "import torch, numba, numpy, mujoco; print(torch.__version__, numba.__version__, numpy.__version__, mujoco.__version__)"
# compile the numba kernels once before the runs start
python3 -m lhd_loading_ros.cli train --variant rld --seed 99 --steps 200 --out /tmp/warm --no-progress --no-resume > /tmp/warm.log 2>&1 || { tail -30 /tmp/warm.log; exit 1; }
echo "warm-up done at $(( $(date +%s) - T0 )) s"
mkdir -p /tmp/r
for spec in rld:bc3 rld:bc03 rlc:bc3; do
  v=${spec%%:*}; c=${spec##*:}
  for s in 0 1 2 3 4; do
    python3 -m lhd_loading_ros.cli train --variant $v --seed $s --out /tmp/r/${v}_${c}/seed_$s --config .devjob/$c.yaml --randomize --no-progress --no-resume > /tmp/r/${v}_${c}_seed_$s.log 2>&1 &
  done
done
LIMIT=${1:-560}
while [ $(( $(date +%s) - T0 )) -lt $LIMIT ] && [ -n "$(jobs -r)" ]; do sleep 5; done
echo "stopped waiting at $(( $(date +%s) - T0 )) s; running: $(jobs -r | wc -l)"
for f in /tmp/r/*/seed_*/evals.csv; do echo "$f $(tail -1 $f | cut -d, -f1,2,3,5,6,15)"; done
cd /tmp/r && tar czf $OUT/res.tgz --exclude=checkpoint.pt --exclude=tb . ; ls -la $OUT
