"""What the viewers draw, as plain arrays (ROS-free): the zones as boxes, the bucket tip's trail,
and the machine's side-view outline. The twin's MarkerArray (lhd_sim_node.twin_markers), the
supervisor's (nodes/supervisor_node.py) and `lhd replay --video` (cli/replay_video.py) all draw
from here, so the three cannot disagree on where a zone or the bucket is.

Coordinates: the pile frame {M} (x forward into the pile, z up); the machine from its base pose
(base_link: the rear axle centre) and joint angles through task.kinematics.ArmKinematics.
"""
from __future__ import annotations

import math
from collections import deque

import numpy as np

from lhd_loading_ros.task.kinematics import PLATE_T, ArmKinematics, _rot_z, arm_offsets, quat_to_mat

# chassis boxes of the MJCF (lhd_sim_node/mjcf.py rear_body / front_body): half length 0.3 m,
# half height 0.1 m, centre 0.12 m above the axle; the front box's centre 0.6 * wheelbase/2
# ahead of the front frame's origin
BODY_HALF_X, BODY_HALF_Z, BODY_CENTRE_Z, FRONT_BODY_AHEAD = 0.3, 0.1, 0.12, 0.6


def zone_boxes(zones, end_height: float = 0.4) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(name, centre xyz, size xyz) of the zones (task.zones.Zones) as boxes in the pile frame:
    `end` (x_min..x_max, |y| <= y_half, z_min..z_min + end_height: the end zone has no upper
    limit), `permitted` (x_obs_start..min(x_obs_end, x_cutoff), |y| <= y_half, floor..z_top,
    the observation zone's height) and `cutoff` (a thin wall at x_cutoff: deeper is restricted)."""
    def box(name, x0, x1, z0, z1, y_half):
        return (name, np.array([(x0 + x1) / 2, 0.0, (z0 + z1) / 2]), np.array([x1 - x0, 2 * y_half, z1 - z0]))
    z = zones
    return [box("end", z.x_min, z.x_max, z.z_min, z.z_min + end_height, z.y_half),
            box("permitted", z.x_obs_start, min(z.x_obs_end, z.x_cutoff), 0.0, z.z_top, z.y_half),
            box("cutoff", z.x_cutoff - 0.005, z.x_cutoff + 0.005, 0.0, z.z_top, z.y_half)]


class TipTrail:
    """The bucket tip's trajectory: points at least `spacing` m apart, the last `max_points`."""

    def __init__(self, spacing: float = 0.005, max_points: int = 2000):
        if not spacing >= 0 or max_points < 2:
            raise ValueError(f"tip trail spacing {spacing!r} m (>= 0) and max_points {max_points} (>= 2) expected")
        self.spacing = spacing
        self.points: deque = deque(maxlen=int(max_points))

    def add(self, xyz) -> bool:
        p = np.array(xyz, dtype=float).reshape(3)      # a copy: callers pass views into MjData
        if not np.isfinite(p).all():
            return False
        if self.points and np.linalg.norm(p - self.points[-1]) < self.spacing:
            return False
        self.points.append(p)
        return True

    def clear(self) -> None:
        self.points.clear()

    def __len__(self) -> int:
        return len(self.points)

    def array(self) -> np.ndarray:
        return np.array(self.points, dtype=float).reshape(-1, 3)


def _box_xz(centre, half_x: float, half_z: float, R: np.ndarray, origin) -> np.ndarray:
    cx, cz = centre
    corners = [(cx - half_x, cz - half_z), (cx + half_x, cz - half_z), (cx + half_x, cz + half_z),
               (cx - half_x, cz + half_z)]
    pts = np.array([[x, 0.0, z] for x, z in corners])
    return (np.asarray(origin, float) + pts @ R.T)[:, [0, 2]]


def machine_outline(kin: ArmKinematics, mc: dict, base_pos, base_quat_wxyz, phi_boom: float, phi_bucket: float,
                    articulation: float = 0.0) -> dict:
    """The machine in the XZ plane of the pile frame: `rear_body`, `front_body` (4 x 2 corner
    arrays), `wheels` ((x, z, radius) of the rear and front axles), `boom` (2 x 2: pivot, bucket
    hinge), `bucket` (4 x 2: the side profile, hinge back plate top, bottom, tip's underside, tip
    side wall top), `tip` (x, z) and `hinge` (x, z). ValueError for an unusable quaternion."""
    R = quat_to_mat(*base_quat_wxyz)
    base = np.asarray(base_pos, dtype=float).reshape(3)
    off = arm_offsets(mc)
    fx = off["front"][0]
    Ra = R @ _rot_z(articulation)
    p_front = base + R @ np.asarray(kin.front)
    p_pivot = p_front + Ra @ np.asarray(kin.boom)
    p_hinge, Rb = kin.bucket_frame(base, R, phi_boom, phi_bucket, articulation)
    tip_x, top, plate = off["tip"][0], off["top_z"], off["plate_z"]
    bottom = plate - PLATE_T / 2
    back_h = mc["bucket_back_height"]
    bucket_local = np.array([[0.0, 0.0, top + back_h], [0.0, 0.0, bottom], [tip_x, 0.0, bottom],
                             [tip_x, 0.0, top + back_h / 2]])
    bucket = (p_hinge + bucket_local @ Rb.T)[:, [0, 2]]
    tip = p_hinge + Rb @ np.asarray(kin.tip)
    r = mc["wheel_radius"]
    front_axle = p_front + Ra @ np.array([fx, 0.0, 0.0])
    return {
        "rear_body": _box_xz((0.0, BODY_CENTRE_Z), BODY_HALF_X, BODY_HALF_Z, R, base),
        "front_body": _box_xz((fx * FRONT_BODY_AHEAD, BODY_CENTRE_Z), BODY_HALF_X, BODY_HALF_Z, Ra, p_front),
        "wheels": [(float(base[0]), float(base[2]), r), (float(front_axle[0]), float(front_axle[2]), r)],
        "boom": np.array([p_pivot[[0, 2]], p_hinge[[0, 2]]]),
        "bucket": bucket,
        "tip": (float(tip[0]), float(tip[2])),
        "hinge": (float(p_hinge[0]), float(p_hinge[2])),
    }


def pile_face(slope_rad: float, toe_x: float, h_pile: float, x_right: float) -> np.ndarray | None:
    """(n, 2) XZ profile of the intact pile (a wedge from the toe at `slope_rad` up to h_pile,
    flat to x_right), or None for an unusable slope."""
    if not (math.isfinite(slope_rad) and 0.0 < slope_rad < math.pi / 2 and math.isfinite(toe_x)):
        return None
    crest = toe_x + h_pile / math.tan(slope_rad)
    return np.array([[toe_x, 0.0], [crest, h_pile], [max(x_right, crest), h_pile], [max(x_right, crest), 0.0]])


class AttemptTrail:
    """The tip trajectory of the current attempt, for the supervisor's markers: a new attempt
    number empties it (and asks the viewer to clear: `clear_pending`), samples are added while
    the attempt is live (armed or running), and it stays as it was after the end until the
    next attempt. `dirty`: something changed since the last `take()`."""

    def __init__(self, spacing: float = 0.005, max_points: int = 4000):
        self.trail = TipTrail(spacing, max_points)
        self.attempt: int | None = None
        self.clear_pending = True          # the first array clears whatever a previous run left
        self.dirty = True

    def update(self, attempt: int | None, live: bool, tip_xyz=None) -> None:
        if attempt is not None and attempt != self.attempt:
            self.attempt = attempt
            self.trail.clear()
            self.clear_pending = self.dirty = True
        if live and tip_xyz is not None and self.trail.add(tip_xyz):
            self.dirty = True

    def take(self) -> tuple[np.ndarray, bool]:
        """(points (n, 3), clear) for the next array; resets dirty and clear_pending."""
        clear = self.clear_pending
        self.clear_pending = self.dirty = False
        return self.trail.array(), clear
