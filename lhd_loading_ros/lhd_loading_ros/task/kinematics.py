"""Forward kinematics of the scaled LHD's arm: the bucket tip (and bottom) pose from the
machine's base pose and the joint angles. One geometry for the MJCF (lhd_sim_node.mjcf
builds its bodies from :func:`arm_offsets`) and for the policy node, which rebuilds the
task state from /lhd/odom and /lhd/joint_states exactly as the environment sees it.

Frames: base_link = rear frame, origin at the rear axle centre (height r above the floor in
the attack pose); x forward, z up. Chain: base_link -> front frame (x + wb/2, central
articulation about z) -> boom (pivot, hinge about +y: negative lifts) -> bucket (hinge
about -y: positive curls back) -> tip / bottom.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lhd_loading_ros.task.state import LhdState

PLATE_T = 0.01      # bucket plate thickness, m
FLOOR_GAP = 0.005   # plate underside above the floor in the attack pose, m
DIGITS = 5          # offsets are rounded as the MJCF writes them, so FK matches MuJoCo exactly


def attack_geometry(mc: dict) -> dict:
    """Key points of the attack pose (relative to the rear axle centre on the floor)."""
    r = mc["wheel_radius"]
    dz_boom = mc["boom_pivot_height"] - mc["bucket_hinge_height"]
    reach = math.sqrt(mc["boom_length"] ** 2 - dz_boom ** 2)
    pivot_x = mc["wheelbase"] + mc["boom_pivot_ahead_of_front_axle"]
    return {
        "r": r,
        "pivot": (pivot_x, mc["boom_pivot_height"]),
        "hinge": (pivot_x + reach, mc["bucket_hinge_height"]),
        "tip": (pivot_x + reach + mc["bucket_tip_ahead_of_hinge"], FLOOR_GAP + PLATE_T),
        "reach": reach,
        "dz_boom": dz_boom,
    }


def arm_offsets(mc: dict) -> dict:
    """Body and site offsets of the kinematic chain, rounded to DIGITS decimals (metres)."""
    g = attack_geometry(mc)
    rd = lambda v: round(v, DIGITS)  # noqa: E731
    fx = mc["wheelbase"] / 2
    plate_z = -(mc["bucket_hinge_height"] - FLOOR_GAP - PLATE_T / 2)
    top_z = plate_z + PLATE_T / 2
    return {
        "front": (rd(fx), 0.0, 0.0),
        "boom": (rd(g["pivot"][0] - fx), 0.0, rd(g["pivot"][1] - g["r"])),
        "bucket": (rd(g["reach"]), 0.0, rd(-g["dz_boom"])),
        "tip": (rd(mc["bucket_tip_ahead_of_hinge"]), 0.0, rd(top_z)),
        "bottom": (0.0, 0.0, rd(plate_z - PLATE_T / 2)),
        "plate_z": rd(plate_z),
        "top_z": rd(top_z),
    }


def _rot_y(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def quat_to_mat(w: float, x: float, y: float, z: float) -> np.ndarray:
    n = math.sqrt(w * w + x * x + y * y + z * z)
    if not n > 0.0 or not math.isfinite(n):
        raise ValueError(f"orientation quaternion ({w}, {x}, {y}, {z}) has no finite, non-zero norm")
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def mat_to_quat(R: np.ndarray) -> tuple[float, float, float, float]:
    """(w, x, y, z) of a rotation matrix (Shepperd's method: the largest of the four squares
    first, so no division by a small number)."""
    t = np.trace(R)
    cands = (t, R[0, 0], R[1, 1], R[2, 2])
    i = int(np.argmax(cands))
    if i == 0:
        w = math.sqrt(1.0 + t) / 2.0
        return w, (R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w)
    if i == 1:
        x = math.sqrt(1.0 + 2 * R[0, 0] - t) / 2.0
        return (R[2, 1] - R[1, 2]) / (4 * x), x, (R[0, 1] + R[1, 0]) / (4 * x), (R[0, 2] + R[2, 0]) / (4 * x)
    if i == 2:
        y = math.sqrt(1.0 + 2 * R[1, 1] - t) / 2.0
        return (R[0, 2] - R[2, 0]) / (4 * y), (R[0, 1] + R[1, 0]) / (4 * y), y, (R[1, 2] + R[2, 1]) / (4 * y)
    z = math.sqrt(1.0 + 2 * R[2, 2] - t) / 2.0
    return (R[1, 0] - R[0, 1]) / (4 * z), (R[0, 2] + R[2, 0]) / (4 * z), (R[1, 2] + R[2, 1]) / (4 * z), z


def nose_down_pitch(R: np.ndarray) -> float:
    """rad, the angle the machine's x axis (the nose) makes below the floor, whatever its heading."""
    return math.atan2(-R[2, 0], math.hypot(R[0, 0], R[1, 0]))


def with_tilt(heading_quat, tilt_quat) -> tuple[float, float, float, float]:
    """The machine's orientation from two sensors: the heading of `heading_quat` (the ArUco
    node's levelled pose) and the roll and pitch of `tilt_quat` (an IMU on the rear frame, whose
    own heading drifts and is dropped). (w, x, y, z)."""
    Rh, Rt = quat_to_mat(*heading_quat), quat_to_mat(*tilt_quat)
    tilt_only = _rot_z(-math.atan2(Rt[1, 0], Rt[0, 0])) @ Rt
    return mat_to_quat(_rot_z(math.atan2(Rh[1, 0], Rh[0, 0])) @ tilt_only)


@dataclass(frozen=True)
class ArmKinematics:
    front: tuple
    boom: tuple
    bucket: tuple
    tip: tuple
    bottom: tuple

    @classmethod
    def from_config(cls, cfg: dict) -> "ArmKinematics":
        o = arm_offsets(cfg["machine"])
        return cls(o["front"], o["boom"], o["bucket"], o["tip"], o["bottom"])

    def bucket_frame(self, base_pos, base_rot: np.ndarray, phi_boom: float, phi_bucket: float,
                     articulation: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """(origin, rotation) of the bucket body in the pile frame."""
        R = base_rot @ _rot_z(articulation)
        p = np.asarray(base_pos, dtype=float) + base_rot @ np.asarray(self.front)
        p = p + R @ np.asarray(self.boom)
        R = R @ _rot_y(phi_boom)
        p = p + R @ np.asarray(self.bucket)
        R = R @ _rot_y(-phi_bucket)
        return p, R

    def tip_and_bottom(self, base_pos, base_rot, phi_boom, phi_bucket, articulation=0.0):
        """((x, y, z) of the tip, pitch of the tip frame, (x, y, z) of the bucket bottom B)."""
        p, R = self.bucket_frame(base_pos, base_rot, phi_boom, phi_bucket, articulation)
        tip = p + R @ np.asarray(self.tip)
        bottom = p + R @ np.asarray(self.bottom)
        return tip, math.atan2(R[2, 0], R[0, 0]), bottom


def state_from_measurements(kin: ArmKinematics, base_pos, base_quat_wxyz, v_x: float, joints: dict,
                            drift_front: bool, drift_rear: bool) -> LhdState:
    """The task state from what the topics carry: base pose (/lhd/odom), v_x
    (twist.linear.x), joint positions and velocities (/lhd/joint_states: boom, bucket, and
    the articulation where measured), drift flags (/lhd/wheel_drift/front, /rear).
    joints: name -> (position, velocity)."""
    for name in ("boom", "bucket"):
        if name not in joints:
            raise ValueError(f"joint '{name}' missing from the joint states; expected boom and bucket")
    R = quat_to_mat(*base_quat_wxyz)
    art = joints.get("articulation", (0.0, 0.0))[0]
    (pb, vb), (pk, vk) = joints["boom"], joints["bucket"]
    tip, pitch, bottom = kin.tip_and_bottom(base_pos, R, pb, pk, art)
    return LhdState(
        x_shovel=float(tip[0]), y_shovel=float(tip[1]), z_shovel=float(tip[2]), phi_shovel=pitch,
        v_x=float(v_x), drift=bool(drift_front or drift_rear), phi_boom=float(pb), dphi_boom=float(vb),
        phi_bucket=float(pk), dphi_bucket=float(vk), x_bottom=float(bottom[0]), z_bottom=float(bottom[2]),
        drift_front=bool(drift_front), drift_rear=bool(drift_rear),
    )
