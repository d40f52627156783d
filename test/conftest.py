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
