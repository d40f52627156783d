import copy
import math

import pytest

from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.task.params import TaskParams


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
