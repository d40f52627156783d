"""Helpers for tests that run real ROS 2 processes over DDS."""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time

import rclpy
from rclpy.executors import SingleThreadedExecutor


def unique_domain_id() -> int:
    """A ROS_DOMAIN_ID for this test process (1..100, the range safe on Linux), so parallel
    test runs and a user's other ROS work do not hear each other. Under pytest-xdist the n workers
    of one run take n neighbouring domains from a block chosen by their common parent's pid, so
    they can never share one (up to 100 workers)."""
    worker = os.environ.get("PYTEST_XDIST_WORKER", "")
    if worker.startswith("gw") and worker[2:].isdigit():
        n = max(1, min(100, int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "2") or 2)))
        blocks = 100 // n
        return 1 + n * (os.getppid() % blocks) + int(worker[2:]) % n
    return 1 + 2 * (os.getpid() % 50)


# Fast DDS logs its own errors from C++ to a process's stdout, e.g. "[RTPS_TRANSPORT_SHM Error] Failed
# init_port fastrtps_port7001: open_and_lock_file failed" when two processes start the shared-memory
# transport at once on a busy machine (it falls back to UDP; the messages arrive). CI failed on such a line
# taken for a process's first line (2026-11-29, -30). The commands whose stdout is read put them on stderr
# (lhd_loading_ros/cli/clean_stdout.py); a test that reads a process's own first line skips them.
FASTDDS_LOG = re.compile(r"^(\x1b\[[0-9;]*m)*\d{4}-\d\d-\d\d \d\d:\d\d:\d\d\.\d+ .*\[.*RTPS_[A-Z_]+.*(Error|Warning)")


def readline_past_middleware(stream) -> str:
    """The next line of a process's stdout that is not a Fast DDS log line ('' at its end)."""
    while True:
        line = stream.readline()
        if not line or not FASTDDS_LOG.match(line):
            return line


_STARTED: list = []      # every RosProcess of this test session, for the leftover check in conftest.py


def started_processes() -> list:
    return list(_STARTED)


DIAGNOSTICS_PERIOD = "diagnostic_updater.period"
TEST_DIAGNOSTICS_PERIOD_S = 0.25


class RosProcess:
    """A node started as a separate process (python -m module --ros-args ...)."""

    def __init__(self, module: str, params: dict, log_path, extra_env: dict | None = None,
                 remaps: dict | None = None, ros_args: list | None = None):
        args = [sys.executable, "-m", module, "--ros-args", *(ros_args or [])]    # e.g. ["--params-file", F]
        # diagnostics at 4 Hz instead of 1 Hz: the tests that wait for a status wait less
        params = {DIAGNOSTICS_PERIOD: TEST_DIAGNOSTICS_PERIOD_S, **params}
        for k, v in params.items():
            args += ["-p", f"{k}:={v}"]
        for k, v in (remaps or {}).items():     # e.g. {"__ns": "/lhd2", "/clock": "/lhd2/clock"}
            args += ["-r", f"{k}:={v}"]
        env = dict(os.environ, PYTHONUNBUFFERED="1", **(extra_env or {}))
        self.log_path = log_path
        self._log = open(log_path, "w")
        self.proc = subprocess.Popen(args, stdout=self._log, stderr=subprocess.STDOUT, env=env,
                                     start_new_session=True)
        _STARTED.append(self)

    def alive(self) -> bool:
        return self.proc.poll() is None

    def stop(self, timeout: float = 10.0) -> int:
        if self._log.closed and self.proc.poll() is not None:
            return self.proc.returncode
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGINT)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait()
        self._log.close()
        return self.proc.returncode

    def log(self) -> str:
        with open(self.log_path) as f:
            return f.read()


def spin_until(node, predicate, timeout: float, step: float = 0.02) -> bool:
    ex = SingleThreadedExecutor(context=node.context)
    ex.add_node(node)
    try:
        t_end = time.monotonic() + timeout
        while time.monotonic() < t_end:
            ex.spin_once(timeout_sec=step)
            if predicate():
                return True
        return predicate()
    finally:
        ex.remove_node(node)


def init_ros():
    os.environ["ROS_DOMAIN_ID"] = str(unique_domain_id())
    if not rclpy.ok():
        rclpy.init()


def shutdown_ros():
    if rclpy.ok():
        rclpy.shutdown()
