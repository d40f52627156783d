"""An IMU bolted onto the rear frame a little askew, and its readings brought back to base_link's axes (ROS-free).

The ArUco node tilts the machine's pose by the IMU's roll and pitch, and the supervisor adds them to the bucket's
final pitch and checks the machine's tilt with them. An IMU mounted 2 deg nose down reads a level machine as
pitched 2 deg: through the whole stack against the twin, `rld_machine` then lost every attempt (0 / 8, 13-19 kg;
2 deg nose up: 1 / 8; docs/real_machine.md "Calibration" step 9). Its mounting, (roll, pitch) = what it reads
with the machine standing on a level floor, is the parameter `imu_zero_deg` of both nodes.

Convention (as lhd_sim_node/sim_sensors.imu_orientation turns a quaternion): the IMU's axes are base_link's turned
by Rx(roll) Ry(pitch), so it reports q_imu = q_base * q_mount and measures f_imu = R_mount^T f_base."""
from __future__ import annotations

import math

import numpy as np

from lhd_loading_ros.task.kinematics import mat_to_quat, quat_to_mat


def level_orientation(q_imu, roll0: float, pitch0: float) -> tuple[float, float, float, float]:
    """base_link's orientation (w, x, y, z) from the IMU's, mounted at (roll0, pitch0) rad: R_imu R_mount^T.
    A quaternion with no finite, non-zero norm is a ValueError (task.kinematics.quat_to_mat)."""
    if roll0 == 0.0 and pitch0 == 0.0:
        return tuple(float(c) for c in q_imu)
    return mat_to_quat(quat_to_mat(*q_imu) @ mount_matrix(roll0, pitch0).T)


def mount_matrix(roll0: float, pitch0: float) -> np.ndarray:
    """R_mount = Rx(roll0) Ry(pitch0): the IMU's axes in base_link's."""
    cr, sr, cp, sp = math.cos(roll0), math.sin(roll0), math.cos(pitch0), math.sin(pitch0)
    return np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]]) @ np.array(
        [[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])


def level_force(f_imu, roll0: float, pitch0: float) -> tuple[float, float, float]:
    """The specific force in base_link's axes (m/s^2) from the IMU's: R_mount f_imu."""
    if roll0 == 0.0 and pitch0 == 0.0:
        return tuple(float(c) for c in f_imu)
    return tuple(float(c) for c in mount_matrix(roll0, pitch0) @ np.asarray(f_imu, dtype=float))


def zero_problem(v) -> str | None:
    """Why [roll, pitch] deg is not an IMU mounting (None: it is)."""
    try:
        r, p = (float(x) for x in v)
    except (TypeError, ValueError):
        return f"expected [roll, pitch] in degrees, got {v!r}"
    if not (math.isfinite(r) and math.isfinite(p) and abs(r) <= 10.0 and abs(p) <= 10.0):
        return f"expected [roll, pitch] within +-10 deg (an IMU's mounting, read on a level floor), got {v!r}"
    return None
