"""`lhd bench sim --ros`: env steps/s of the loading task through one sim node over DDS
(LhdLoadingRos-v0: command out, transition back, resets through parameters and the reset
service), next to the same loop on the in-process LhdLoading-v0.

A lockstep sim node is started as its own process in a namespace of its own (on this
ROS_DOMAIN_ID), driven with the same random actions, resets included, and stopped. Both figures
are the best of `rounds` alternating runs (other load on the machine only slows a run down).
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import time

import numpy as np

from .bench import _episode_loop
from .env import LhdLoadingEnv
from .ros_env import LhdLoadingRosEnv


def _loop(env, actions: np.ndarray, seed: int) -> tuple[float, int]:
    """bench_sim's episode loop (the same actions and resets), timed."""
    t0 = time.perf_counter()
    resets = _episode_loop(env, actions, seed)
    return time.perf_counter() - t0, resets


def bench_sim_ros(steps: int = 1000, seed: int = 0, config=None, rounds: int = 3, timeout: float = 60.0) -> dict:
    if steps < 1 or rounds < 1:
        raise ValueError(f"steps and rounds must be >= 1, got {steps}, {rounds}")
    actions = np.random.default_rng(seed).uniform(-1.0, 1.0, size=(steps, 3))
    ns = f"/bench_{os.getpid()}"
    log = tempfile.NamedTemporaryFile("w", prefix="lhd_bench_sim_node_", suffix=".log", delete=False)
    args = [sys.executable, "-m", "lhd_sim_node.sim_node", "--ros-args", "-p", "mode:=lockstep", "-r", f"__ns:={ns}"]
    if config:
        args[-4:-4] = ["-p", f"config:={os.path.abspath(config)}"]
    node = subprocess.Popen(args, stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
                            env=dict(os.environ, PYTHONUNBUFFERED="1"))
    ros, ok = None, False
    try:
        ros = LhdLoadingRosEnv("rld", config=config, namespace=ns, timeout=timeout)
        local = LhdLoadingEnv("rld", config=config)
        _loop(ros, actions[:50], seed)           # warm-up: DDS discovery, numba and MuJoCo caches
        _loop(local, actions[:50], seed)
        ros_t, loc_t, resets = [], [], 0
        for _ in range(rounds):
            t, resets = _loop(ros, actions, seed)
            ros_t.append(t)
            loc_t.append(_loop(local, actions, seed)[0])
        ok = True
    except BaseException:
        if node.poll() is not None:
            log.flush()
            print(f"lhd bench sim --ros: the sim node exited ({node.returncode}); its log: {log.name}", file=sys.stderr)
        raise
    finally:
        if ros is not None:
            ros.close()
        if node.poll() is None:
            os.killpg(node.pid, signal.SIGINT)
            try:
                node.wait(10)
            except subprocess.TimeoutExpired:
                os.killpg(node.pid, signal.SIGKILL)
                node.wait()
        log.close()
        if ok:
            os.unlink(log.name)         # kept (and named) only when something failed
    ros_sps, loc_sps = steps / min(ros_t), steps / min(loc_t)
    return {
        "ros_env_steps_per_s": round(ros_sps, 1),
        "in_process_env_steps_per_s": round(loc_sps, 1),
        "ros_over_in_process": round(ros_sps / loc_sps, 3),
        "ros_ms_per_step_overhead": round(1000.0 * (1.0 / ros_sps - 1.0 / loc_sps), 3),
        "steps": steps,
        "rounds": rounds,
        "resets": resets,
        "ros_domain_id": int(os.environ.get("ROS_DOMAIN_ID", "0") or 0),
        "rmw": os.environ.get("RMW_IMPLEMENTATION", "default"),
    }
