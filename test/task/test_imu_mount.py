"""task/imu_mount.py: an IMU bolted on askew, its readings brought back to base_link's axes. The readings come from
the digital twin's own IMU model (lhd_sim_node/sim_sensors.py, independent code) turned by the mounting."""
from __future__ import annotations

import math

import numpy as np
import pytest

from lhd_loading_ros.task.imu_mount import level_force, level_orientation, mount_matrix, zero_problem
from lhd_loading_ros.task.kinematics import nose_down_pitch, quat_to_mat
from lhd_sim_node import sim_sensors as ss

DEG = math.radians


@pytest.mark.parametrize("mount", [(0.0, 2.0), (-1.5, 0.0), (3.0, -4.0)])
@pytest.mark.parametrize("true_pitch, yaw", [(0.0, 0.0), (5.0, 0.0), (-3.0, 20.0)])
def test_the_mounting_taken_off_gives_base_links_orientation_and_force(mount, true_pitch, yaw):
    mr, mp = DEG(mount[0]), DEG(mount[1])
    # the machine: yawed, then pitched nose down about its own y (a rear lifting)
    qy = (math.cos(DEG(yaw) / 2), 0.0, 0.0, math.sin(DEG(yaw) / 2))
    q_base = ss.imu_orientation(qy, 0.0, DEG(true_pitch))
    q_imu = ss.imu_orientation(q_base, mr, mp)           # what the askew IMU reports
    a_world = np.array([0.4, -0.1, 0.05])
    f_base = ss.imu_specific_force(q_base, a_world)
    f_imu = mount_matrix(mr, mp).T @ f_base              # what its accelerometer measures
    assert np.abs(quat_to_mat(*q_imu) - quat_to_mat(*q_base)).max() > 1e-3      # the mounting shows
    q = level_orientation(q_imu, mr, mp)
    np.testing.assert_allclose(quat_to_mat(*q), quat_to_mat(*q_base), atol=1e-12)
    assert nose_down_pitch(quat_to_mat(*q)) == pytest.approx(DEG(true_pitch), abs=1e-12)
    np.testing.assert_allclose(level_force(f_imu, mr, mp), f_base, atol=1e-12)


def test_a_level_machine_read_by_an_imu_2_deg_nose_down():
    """By hand: the IMU reads pitch +2 deg and gravity with a forward component -g sin 2 deg on a level machine;
    taken off, both are level again."""
    q_imu = ss.imu_orientation((1.0, 0.0, 0.0, 0.0), 0.0, DEG(2.0))
    assert nose_down_pitch(quat_to_mat(*q_imu)) == pytest.approx(DEG(2.0))
    f_imu = mount_matrix(0.0, DEG(2.0)).T @ np.array([0.0, 0.0, 9.81])
    assert f_imu[0] == pytest.approx(-9.81 * math.sin(DEG(2.0))) and f_imu[2] == pytest.approx(9.81 * math.cos(DEG(2.0)))
    np.testing.assert_allclose(quat_to_mat(*level_orientation(q_imu, 0.0, DEG(2.0))), np.eye(3), atol=1e-12)
    np.testing.assert_allclose(level_force(f_imu, 0.0, DEG(2.0)), (0.0, 0.0, 9.81), atol=1e-12)
    assert level_orientation(q_imu, 0.0, 0.0) == pytest.approx(q_imu)


def test_bad_mountings_are_refused_with_what_is_expected():
    assert zero_problem([0.0, 2.0]) is None
    assert "within +-10 deg" in zero_problem([0.0, 12.0])
    assert "within +-10 deg" in zero_problem([math.nan, 0.0])
    assert "expected [roll, pitch]" in zero_problem([1.0])
