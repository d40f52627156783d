"""Fixtures shared by the task tests."""
import pytest

from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.task.params import TaskParams


@pytest.fixture(scope="session")
def paper_params():
    """TaskParams with the paper's table normalisers (x_obs 1.1 m, d_end_max 0.87 m) instead of
    the ones derived from the gravel pile family (task.normalisers_from_pile: 0), for hand numbers."""
    cfg = load_config()
    cfg["task"]["normalisers_from_pile"] = 0
    return TaskParams.from_config(cfg)
