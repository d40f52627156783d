"""The estimation-error arithmetic of `lhd up twin` (pure functions, no nodes): what the stack's
planar motion leaves out of the final pitch, computed against a hand-made rotation."""
import math

import numpy as np
import pytest

from lhd_loading_ros.cli.up_twin import latest_before, pitch_dropped_deg
from lhd_loading_ros.task.kinematics import ArmKinematics


def quat_about(axis, angle):
    """(w, x, y, z) of a rotation by `angle` about a unit axis."""
    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    return (math.cos(angle / 2), *(math.sin(angle / 2) * a))


@pytest.fixture
def kin(cfg):
    return ArmKinematics.from_config(cfg)


JOINTS = {"boom": (-0.3, 0.0), "bucket": (0.4, 0.0)}


@pytest.mark.parametrize("theta_deg", [-3.0, -0.7, 0.0, 0.5, 2.5])
def test_a_pure_pitch_of_the_machine_is_what_planar_motion_drops(kin, theta_deg):
    # the arm turns about the machine's y axis, so a machine pitched by theta about y turns the tip
    # frame by theta too: the tip pitch, atan2(R[2,0], R[0,0]), changes by -theta (a rotation by
    # +theta about y maps x to (cos, 0, -sin)), whatever the joint angles
    th = math.radians(theta_deg)
    pose = (0.0, (-1.0, 0.0, 0.137), quat_about((0, 1, 0), th))
    assert pitch_dropped_deg(kin, pose, JOINTS) == pytest.approx(-theta_deg, abs=1e-9)
    other = {"boom": (-0.1, 0.0), "bucket": (0.9, 0.0)}
    assert pitch_dropped_deg(kin, pose, other) == pytest.approx(-theta_deg, abs=1e-9)


def test_heading_alone_drops_nothing(kin):
    pose = (0.0, (-1.0, 0.2, 0.137), quat_about((0, 0, 1), math.radians(7.0)))
    assert pitch_dropped_deg(kin, pose, JOINTS) == pytest.approx(0.0, abs=1e-9)


def test_latest_before_picks_the_last_entry_at_or_before():
    series = [(1.0, "a"), (2.0, "b"), (3.0, "c")]
    assert latest_before(series, 0.5) is None
    assert latest_before(series, 2.0) == (2.0, "b")
    assert latest_before(series, 2.9) == (2.0, "b")
    assert latest_before(series, 9.0) == (3.0, "c")
