import copy
import math
import os

import pytest

from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.task.params import TaskParams


# the launchers (lhd up sim / real / twin, lhd bench twin) listen this long for a stack already on
# their domain before starting theirs (ros/params.discovery_wait_s, 3 s for users): one host
# discovers in well under a second, and the suite starts about twenty of them
os.environ.setdefault("LHD_DISCOVERY_WAIT_S", "1.0")


@pytest.fixture(scope="session")
def cfg_session():
    return load_config()


@pytest.fixture
def cfg(cfg_session):
    return copy.deepcopy(cfg_session)


@pytest.fixture(scope="session")
def params(cfg_session):
    return TaskParams.from_config(cfg_session)


def deg(x):
    return math.radians(x)


@pytest.fixture(autouse=True)
def _no_leftover_nodes():
    """A node process a test started and did not stop (an assertion failed before its stop) is
    stopped here, so that it cannot keep loading the machine or talking on the test's domain."""
    try:
        from rosutil import started_processes
    except ImportError:       # no rclpy: no node processes either
        yield
        return
    before = {id(p) for p in started_processes()}
    yield
    for p in started_processes():
        if id(p) not in before and p.alive():
            p.stop(timeout=5.0)


@pytest.fixture(autouse=True, scope="session")
def _no_leftover_nodes_at_the_end():
    """What the per-test check cannot see: a process a module fixture started and a test replaced
    without stopping (a failed test left a supervisor running after its session, found 2026-11-28)."""
    yield
    try:
        from rosutil import started_processes
    except ImportError:
        return
    for p in started_processes():
        if p.alive():
            p.stop(timeout=5.0)


_ROS_SOURCE = ("import rclpy", "from rclpy", "import rosutil", "from rosutil", "import subprocess",
               "from subprocess", "RosProcess", "FakeMachine", "supervisor_rig")
_ros_modules: dict = {}


def _talks_to_processes(module) -> bool:
    """The module starts node processes or talks over DDS (rclpy, rosutil, subprocess): its tests
    depend on timing and run in `make test`'s second pass (one file per worker); the others run in
    the first, on several workers. A module with SERIAL = True runs in `make test-stack`, alone
    (pytest_collection_modifyitems).
    A module that starts processes but whose results do not depend on timing (lockstep sim nodes,
    command-line runs that only compute) says so with `PARALLEL_SAFE = True` at its top level and
    runs with the pure tests (each xdist worker has its own DDS domain, test/rosutil.py)."""
    path = getattr(module, "__file__", None)
    if path not in _ros_modules:
        try:
            text = open(path, encoding="utf-8").read() if path else ""
        except OSError:
            text = ""
        safe = getattr(module, "PARALLEL_SAFE", False) is True
        _ros_modules[path] = any(s in text for s in _ROS_SOURCE) and not safe
    return _ros_modules[path]


def pytest_configure(config):
    # rcl's own log files of every node the suite starts: in the temporary folder, not ~/.ros/log (a review found
    # 43 MB there, mostly the suite's)
    if "ROS_LOG_DIR" not in os.environ and "ROS_HOME" not in os.environ:
        import tempfile

        os.environ["ROS_LOG_DIR"] = os.path.join(tempfile.gettempdir(), "lhd_test_ros_logs")
    config.addinivalue_line("markers", "ros: starts node processes or talks over DDS (depends on timing: `make test` "
                                       "runs these on TEST_JOBS workers, one test file per worker)")
    config.addinivalue_line("markers", "serial: a whole stack or pipeline end to end (twin, `lhd up sim` / `lhd up "
                                       "real`, sensor streams at their rates, training over ROS, a Ray sweep): on 2 "
                                       "cores two of them starve each other, so `make test-stack` runs them alone, "
                                       "not in the default `make test` (module-level SERIAL = True)")
    config.addinivalue_line("markers", "parallel_safe: starts processes, but its results do not depend on timing "
                                       "(lockstep, generous waits): runs with the pure tests")


def pytest_collection_modifyitems(config, items):
    for item in items:
        module = getattr(item, "module", None)
        if module is not None and getattr(module, "SERIAL", False) is True:
            item.add_marker(pytest.mark.ros)             # the stack pass, whatever PARALLEL_SAFE says
            item.add_marker(pytest.mark.serial)
        elif module is not None and _talks_to_processes(module) and item.get_closest_marker("parallel_safe") is None:
            item.add_marker(pytest.mark.ros)
