"""The ArUco node's tilt correction (perception/aruco.py roll_pitch, tilted_base_position): a machine
tilted about the wheels on the floor, built by hand in the test, seen through an exact pinhole
ray, is placed where it is; the levelled estimate is off by the amounts the docstring names."""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lhd_loading_ros.perception.aruco import position_on_plane, roll_pitch, tilted_base_position
from lhd_loading_ros.perception.geometry import quaternion_xyzw, rpy_matrix, transform

WHEELBASE, R_WHEEL = 0.80, 0.137
M_BASE = np.array([-0.10, 0.0, 0.213])          # the marker's centre in base_link (real_machine.yaml)
T_PILE_CAM = transform((-0.5, 0.0, 1.5), (math.pi, 0.0, -math.pi / 2))   # the node's default camera


def tilted_machine(x_front: float, yaw: float, pitch: float, roll: float = 0.0):
    """base_link's position and rotation for a machine whose pivot axle's floor contact stays at
    (x_front..., z = 0): nose down about the front axle, nose up about the rear one."""
    R = rpy_matrix(roll, pitch, yaw)
    contact_b = np.array([WHEELBASE if pitch >= 0 else 0.0, 0.0, -R_WHEEL])
    contact_w = np.array([x_front, 0.3, 0.0])
    return contact_w - R @ contact_b, R


def ray_of(p_world):
    pc = np.linalg.inv(T_PILE_CAM) @ np.append(p_world, 1.0)
    return pc[:2] / pc[2]


@pytest.mark.parametrize("pitch_deg", [0.0, 3.0, 10.0, 25.0, -4.0])
def test_tilted_machine_is_placed_exactly(pitch_deg):
    yaw = math.radians(2.0)
    p_base, R = tilted_machine(0.9, yaw, math.radians(pitch_deg), roll=math.radians(1.0))
    marker = p_base + R @ M_BASE
    got = tilted_base_position(ray_of(marker), T_PILE_CAM, yaw, math.radians(1.0), math.radians(pitch_deg), M_BASE,
                               WHEELBASE, -R_WHEEL)
    np.testing.assert_allclose(got, p_base, atol=1e-9)
    # the levelled estimate: the ray met at the upright marker height, the upright lever arm
    level = position_on_plane(ray_of(marker), T_PILE_CAM, R_WHEEL + M_BASE[2]) - rpy_matrix(0, 0, yaw) @ M_BASE
    err = abs(level[0] - p_base[0])
    if pitch_deg == 10.0:
        # rise of the marker 0.8 sin 10 + ..., met short; plus the lever arm 0.213 sin 10: several cm
        assert 0.03 < err < 0.15, err
    if pitch_deg == 0.0:
        assert err < 1e-3           # the 1 deg roll alone moves x by a tenth of a millimetre


def test_upright_machine_matches_the_upright_plane():
    p_base, R = tilted_machine(1.2, 0.0, 0.0)
    assert p_base[2] == pytest.approx(R_WHEEL)
    marker = p_base + R @ M_BASE
    assert marker[2] == pytest.approx(0.35)


@settings(max_examples=200, deadline=None)
@given(st.floats(-math.pi + 0.01, math.pi - 0.01), st.floats(-1.2, 1.2), st.floats(-math.pi, math.pi))
def test_roll_pitch_of_a_quaternion(roll, pitch, yaw):
    q = quaternion_xyzw(rpy_matrix(roll, pitch, yaw))
    r, p = roll_pitch(*q)
    assert p == pytest.approx(pitch, abs=1e-9)
    assert math.remainder(r - roll, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)


def test_roll_pitch_refuses_a_non_rotation():
    for q in ((0, 0, 0, 0), (float("nan"), 0, 0, 1)):
        with pytest.raises(ValueError, match="not a rotation"):
            roll_pitch(*q)
    # a quaternion off unit norm is a corrupt message, not a rotation to normalise: (0, 0.1, 0,
    # 0.49), norm 0.5, read as a 23 deg pitch before 2026-11-28; float rounding passes
    for q in ((0, 0, 0, 2.0), (0, 0.1, 0, 0.49), (0, 0, 0, 0.985)):
        with pytest.raises(ValueError, match="expected a unit quaternion"):
            roll_pitch(*q)
    assert roll_pitch(0, 0, 0, 1.0 + 1e-7) == (0.0, 0.0) and roll_pitch(0, 0, 0, 0.995) == (0.0, 0.0)
    # nose down: REP 103's positive pitch
    r, p = roll_pitch(*quaternion_xyzw(rpy_matrix(0.0, math.radians(10), 0.0)))
    assert p == pytest.approx(math.radians(10)) and rpy_matrix(0.0, p, 0.0)[2, 0] < 0   # the nose (x) points down
