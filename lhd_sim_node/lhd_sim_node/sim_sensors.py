"""Simulated camera and LiDAR of the digital twin, and the geometry of its markers (ROS-free).

The twin node (twin_node.py) turns these into ROS messages; the real perception nodes read them
as they read the real sensors. Poses come from the same parameter sections the real nodes read
(config/real_machine.yaml: `aruco_pose_node`, `lidar_slope_node`), so the simulated sensors and
the nodes can never disagree on where a sensor or the marker is.

Camera (CameraModel, camera_image): the ArUco marker on the machine's rear frame seen by the
overhead camera. The marker's pose is base_link's pose from the simulator composed with the
INVERSE of marker_to_base (the ArUco node's parameter is base_link in the marker frame), the
image an exact pinhole projection of the marker's texture (perception.synthetic.render: a
homography warp of the printed marker, which is exact for a plane) on a fixed floor texture,
then exposure (gain, offset), optical blur, sensor noise and randomly dropped frames. MuJoCo's
own renderer is not used: the MJCF carries no marker texture, a software GL (the only backend on
a headless machine) is slow, and the projection is exact and deterministic.

LiDAR (LidarModel, lidar_scan): rays in the scanner's XY plane, moved into the pile frame with
the sensor's pose, cast through the XZ profile of the scene: the floor, the CURRENT voxel pile
along the scan plane's slice (column tops after the bucket's cuts, the wedge's crest behind its
back end up to the draw point's back wall), optionally the draw point's ceiling and drawbell
(perception.synthetic.DrawPoint) and the machine's own bodies (machine_segments). Range noise,
range limits, angular step and outliers as a real scanner has them.

Markers: pile surface polylines, zone boxes, the bucket tip's trail and the FEE force arrow as
plain arrays (twin_markers.marker_array makes the visualization_msgs/MarkerArray).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from lhd_loading_ros.perception.aruco import dictionary
from lhd_loading_ros.perception.geometry import transform
from lhd_loading_ros.perception.synthetic import FAR, DrawPoint, cast_rays, marker_texture, render, scene_segments
from lhd_loading_ros.task.viz import TipTrail, zone_boxes  # noqa: F401  (shared with the supervisor's markers)

# The real nodes' defaults (aruco_pose_node.py, lidar_slope_node.py): a key missing from a
# parameter section means the node runs with its default, so the simulated sensor must too.
# test_sim_sensors.py checks these against the nodes' sources.
ARUCO_DEFAULTS = {
    "dictionary": "DICT_4X4_50", "marker_id": 7, "marker_size": 0.12,
    "camera_xyz": [-0.5, 0.0, 1.5], "camera_rpy": [math.pi, 0.0, -math.pi / 2],
    "marker_to_base_xyz": [0.10, 0.0, -0.213], "marker_to_base_rpy": [0.0, 0.0, 0.0],
}
LIDAR_DEFAULTS = {"sensor_xyz": [0.6, 0.0, 1.6], "sensor_rpy": [math.pi / 2, 0.0, 0.0]}
MARKER_PX = 200          # texture pixels across the black square (render's marker_px)
NOISE_FIELDS = 4         # sensor-noise fields a camera crops its frames' noise from (render's noise_bank)


def _section(section: dict | None, defaults: dict, name: str) -> dict:
    """The node's parameters from a section of a ROS parameter file: either the
    `ros__parameters` dict itself or the node's section holding it; missing keys take the node's
    defaults. ValueError naming the key for a vector that is not 3 finite numbers."""
    s = dict(section or {})
    if "ros__parameters" in s:
        s = dict(s["ros__parameters"] or {})
    out = dict(defaults)
    out.update({k: v for k, v in s.items() if k in defaults})
    for k, v in out.items():
        if k.endswith(("_xyz", "_rpy")):
            try:
                vals = [float(x) for x in v]
            except (TypeError, ValueError):
                raise ValueError(f"{name}.{k} = {v!r}: expected 3 numbers") from None
            if len(vals) != 3 or not all(math.isfinite(x) for x in vals):
                raise ValueError(f"{name}.{k} = {v!r}: expected 3 finite numbers")
            out[k] = vals
    return out


def _pose_matrix(pos, quat_wxyz) -> np.ndarray:
    w, x, y, z = (float(q) for q in quat_wxyz)
    n = math.sqrt(w * w + x * x + y * y + z * z)
    if not (math.isfinite(n) and n > 1e-9) or not all(math.isfinite(float(p)) for p in pos):
        raise ValueError(f"base pose {list(pos)} / {list(quat_wxyz)}: expected a finite position and a non-zero quaternion")
    w, x, y, z = w / n, x / n, y / n, z / n
    T = np.eye(4)
    T[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                 [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                 [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]
    T[:3, 3] = [float(p) for p in pos]
    return T


# ---------------------------------------------------------------------------------- camera
@dataclass(frozen=True, eq=False)
class CameraModel:
    width: int
    height: int
    K: np.ndarray                 # 3x3 intrinsics (no distortion: the images are rectified)
    T_pile_cam: np.ndarray        # camera optical frame in the pile frame
    T_base_marker: np.ndarray     # marker in base_link = inverse of the node's marker_to_base
    marker_size: float            # m, side of the black square
    marker_id: int
    dictionary: str
    noise: float                  # grey levels, standard deviation of the sensor noise
    blur: float                   # px, 3 sigma of the optical Gaussian blur (0: sharp)
    exposure: float               # gain on the scene's brightness (1: nominal)
    offset: float                 # grey levels added (black level)
    dropout: float                # probability that a frame is lost
    texture: np.ndarray = field(repr=False)      # the printed marker after exposure, uint8
    background: np.ndarray = field(repr=False)   # the floor around it after exposure, uint8
    noise_bank: np.ndarray | None = field(default=None, repr=False)   # standard normal fields (render's)

    @classmethod
    def from_params(cls, aruco_section: dict | None, width: int = 640, height: int = 480, f: float | None = None,
                    noise: float = 2.0, blur: float = 1.0, exposure: float = 1.0, dropout: float = 0.0,
                    offset: float = 0.0, background_seed: int = 0) -> "CameraModel":
        """From the ArUco node's parameter section (its `ros__parameters`, or the section holding
        them; keys missing take the node's defaults). `f` is the focal length in pixels (default
        0.94 * width, a 56 deg horizontal field of view)."""
        p = _section(aruco_section, ARUCO_DEFAULTS, "aruco_pose_node")
        width, height = int(width), int(height)
        if width < 16 or height < 16:
            raise ValueError(f"camera image {width}x{height}: expected at least 16x16 pixels")
        f = 0.94 * width if f is None else float(f)
        checks = [(f > 0, f"camera focal length f = {f!r} px: expected > 0"),
                  (noise >= 0, f"camera noise = {noise!r}: expected >= 0 grey levels"),
                  (blur >= 0, f"camera blur = {blur!r}: expected >= 0 px"),
                  (exposure > 0, f"camera exposure = {exposure!r}: expected a gain > 0"),
                  (math.isfinite(offset), f"camera offset = {offset!r}: expected a finite number of grey levels"),
                  (0.0 <= dropout < 1.0, f"camera dropout = {dropout!r}: expected a probability in [0, 1)"),
                  (float(p["marker_size"]) > 0, f"aruco_pose_node.marker_size = {p['marker_size']!r}: expected > 0 m")]
        for ok, why in checks:
            if not ok:
                raise ValueError(why)
        dictionary(p["dictionary"])          # ValueError naming a bad dictionary
        K = np.array([[f, 0.0, width / 2.0], [0.0, f, height / 2.0], [0.0, 0.0, 1.0]])
        tex = marker_texture(p["dictionary"], int(p["marker_id"]), MARKER_PX, MARKER_PX // 4)
        rng = np.random.default_rng(background_seed)
        bg = cv2.GaussianBlur((90 + 40 * rng.random((height, width))).astype(np.uint8), (0, 0), 3)

        def expose(img):   # the scene's radiance through the exposure; the sensor saturates
            return np.clip(exposure * img.astype(np.float64) + offset, 0, 255).astype(np.uint8)

        return cls(width, height, K, transform(p["camera_xyz"], p["camera_rpy"]),
                   np.linalg.inv(transform(p["marker_to_base_xyz"], p["marker_to_base_rpy"])),
                   float(p["marker_size"]), int(p["marker_id"]), str(p["dictionary"]), float(noise), float(blur),
                   float(exposure), float(offset), float(dropout), expose(tex), expose(bg),
                   rng.standard_normal((NOISE_FIELDS, height + 32, width + 32), dtype=np.float32))

    def marker_pose(self, base_pos, base_quat_wxyz) -> np.ndarray:
        """4x4 pose of the marker (centre, z out of the printed face) in the pile frame."""
        return _pose_matrix(base_pos, base_quat_wxyz) @ self.T_base_marker

    def marker_corners_px(self, base_pos, base_quat_wxyz) -> np.ndarray | None:
        """(4, 2) pixel coordinates of the black square's corners (None: behind the camera)."""
        T = np.linalg.inv(self.T_pile_cam) @ self.marker_pose(base_pos, base_quat_wxyz)
        s = self.marker_size / 2.0
        pc = np.array([[-s, s, 0], [s, s, 0], [s, -s, 0], [-s, -s, 0]]) @ T[:3, :3].T + T[:3, 3]
        if (pc[:, 2] <= 1e-3).any():
            return None
        return (pc[:, :2] / pc[:, 2:3]) @ self.K[:2, :2].T + self.K[:2, 2]

    def visible(self, base_pos, base_quat_wxyz) -> bool:
        """The whole marker is in the image, in front of the camera, its face toward it."""
        uv = self.marker_corners_px(base_pos, base_quat_wxyz)
        if uv is None:
            return False
        T = np.linalg.inv(self.T_pile_cam) @ self.marker_pose(base_pos, base_quat_wxyz)
        facing = float(T[:3, 2] @ T[:3, 3]) < 0.0        # marker normal toward the camera
        return facing and bool(((uv >= 0) & (uv <= [self.width - 1, self.height - 1])).all())

    def camera_info(self) -> dict:
        """sensor_msgs/CameraInfo fields (plumb_bob, no distortion, P = [K | 0])."""
        P = np.zeros((3, 4))
        P[:, :3] = self.K
        return {"width": self.width, "height": self.height, "distortion_model": "plumb_bob", "d": [0.0] * 5,
                "k": self.K.ravel().tolist(), "r": np.eye(3).ravel().tolist(), "p": P.ravel().tolist()}


def camera_image(model: CameraModel, base_pos, base_quat_wxyz, rng: np.random.Generator) -> np.ndarray | None:
    """The camera's mono8 frame (height x width uint8) with the machine's base_link at
    (base_pos, base_quat_wxyz) in the pile frame (MuJoCo's order: w, x, y, z), or None for a
    dropped frame. A marker behind the camera or facing away leaves only the floor."""
    if model.dropout > 0.0 and rng.random() < model.dropout:
        return None
    T = np.linalg.inv(model.T_pile_cam) @ model.marker_pose(base_pos, base_quat_wxyz)
    h = model.marker_size * model.texture.shape[0] / MARKER_PX / 2.0      # with the white quiet zone
    quad = np.array([[-h, h, 0], [h, h, 0], [h, -h, 0], [-h, -h, 0]]) @ T[:3, :3].T + T[:3, 3]
    if (quad[:, 2] <= 1e-3).any() or float(T[:3, 2] @ T[:3, 3]) >= 0.0:
        img = model.background.astype(np.float64)
        if model.blur:
            img = cv2.GaussianBlur(img, (0, 0), model.blur / 3.0)
        img += rng.normal(0.0, model.noise, img.shape)
        return np.clip(img, 0, 255).astype(np.uint8)
    return render(model.K, model.width, model.height, T, model.texture, model.marker_size, rng,
                  noise=model.noise, blur=model.blur, background=model.background, marker_px=MARKER_PX,
                  noise_bank=model.noise_bank)


# ---------------------------------------------------------------------------------- LiDAR
@dataclass(frozen=True)
class LidarModel:
    T_pile_sensor: np.ndarray
    n: int                    # beams per scan
    angle_min: float          # rad, in the scanner's XY plane
    angle_max: float
    noise: float              # m, range noise standard deviation
    outliers: float           # fraction of beams with a random range (dust, mixed pixels)
    range_min: float          # m
    range_max: float
    back_wall_gap: float      # m from the wedge's back end to the draw point's back wall

    @classmethod
    def from_params(cls, lidar_section: dict | None, n: int = 720, angle_min: float = -math.radians(170),
                    angle_max: float = -math.radians(10), noise: float = 0.01, outliers: float = 0.02,
                    range_min: float = 0.05, range_max: float = 8.0, back_wall_gap: float = 0.3) -> "LidarModel":
        """From the LiDAR slope node's parameter section (sensor_xyz, sensor_rpy; missing keys
        take the node's defaults). The default beams cover -170..-10 deg: with the node's
        default roll of 90 deg the scanner's -y is down, so they sweep the floor before the
        pile, the face and the crest."""
        p = _section(lidar_section, LIDAR_DEFAULTS, "lidar_slope_node")
        n = int(n)
        checks = [(n >= 2, f"lidar n = {n}: expected at least 2 beams"),
                  (math.isfinite(angle_min) and math.isfinite(angle_max) and angle_min < angle_max,
                   f"lidar angles [{angle_min!r}, {angle_max!r}]: expected finite angle_min < angle_max (rad)"),
                  (noise >= 0, f"lidar noise = {noise!r}: expected >= 0 m"),
                  (0.0 <= outliers < 1.0, f"lidar outliers = {outliers!r}: expected a fraction in [0, 1)"),
                  (0.0 < range_min < range_max, f"lidar range [{range_min!r}, {range_max!r}]: expected 0 < min < max (m)"),
                  (back_wall_gap >= 0, f"lidar back_wall_gap = {back_wall_gap!r}: expected >= 0 m")]
        for ok, why in checks:
            if not ok:
                raise ValueError(why)
        return cls(transform(p["sensor_xyz"], p["sensor_rpy"]), n, float(angle_min), float(angle_max), float(noise),
                   float(outliers), float(range_min), float(range_max), float(back_wall_gap))

    @property
    def angle_increment(self) -> float:
        return (self.angle_max - self.angle_min) / (self.n - 1)

    def beam_directions(self) -> np.ndarray:
        """(n, 3) unit directions of the beams in the pile frame."""
        a = self.angle_min + self.angle_increment * np.arange(self.n)
        return np.column_stack([np.cos(a), np.sin(a), np.zeros(self.n)]) @ self.T_pile_sensor[:3, :3].T

    def laser_scan_fields(self) -> dict:
        """sensor_msgs/LaserScan fields other than header and ranges."""
        return {"angle_min": self.angle_min, "angle_max": self.angle_max, "angle_increment": self.angle_increment,
                "range_min": self.range_min, "range_max": self.range_max}


def _slice_index(pile, y: float) -> int:
    return int(np.argmin(np.abs(pile.y_centers - y)))


def pile_profile(pile, y: float = 0.0, back_wall_gap: float = 0.3) -> np.ndarray:
    """(n, 2) XZ polyline of the pile's CURRENT surface in the slice nearest y, from the toe:
    (0, 0), the column tops at the column centres (after the bucket's cuts), the wedge's crest
    (L, h), the crest continued to the draw point's back wall at L + back_wall_gap (the
    material behind the wedge is held there: VoxelPile.surface_height). The floor before the
    toe and the wall above the crest are not in it (pile_segments adds them)."""
    j = _slice_index(pile, y)
    x = np.concatenate([[0.0], pile.x_centers, [pile.L, pile.L + back_wall_gap]])
    z = np.concatenate([[0.0], pile.top[j], [pile.h, pile.h]])
    return np.column_stack([x, z])


def pile_segments(pile, y: float = 0.0, back_wall_gap: float = 0.3) -> np.ndarray:
    """(m, 4) segments x0, z0, x1, z1 of floor, pile surface and back wall in the slice nearest y."""
    prof = pile_profile(pile, y, back_wall_gap)
    end = prof[-1]
    pts = np.vstack([[-FAR, 0.0], prof, [end[0], FAR]])
    return np.column_stack([pts[:-1], pts[1:]])


def draw_point_segments(clutter: DrawPoint) -> np.ndarray:
    """(m, 4) ceiling and drawbell of the draw point (perception.synthetic's geometry, without
    its stand-in machine: the twin has the real one, machine_segments)."""
    return scene_segments(math.radians(45.0), 0.0, 0.5, 1.0, replace(clutter, machine=False))[4:]


BODY_GEOMS = ("rear_body", "front_body", "bucket_plate", "bucket_back", "boom")


def machine_segments(model, data, y: float = 0.0, geoms=BODY_GEOMS) -> np.ndarray:
    """(m, 4) XZ outlines of the simulated machine's box and capsule geoms that cross the plane
    at y (MuJoCo model and data after mj_kinematics): the bodies, the bucket and the boom hide
    what is behind them from the LiDAR, as the real machine does."""
    segs = []
    for name in geoms:
        g = model.geom(name).id
        c, R, size = data.geom_xpos[g], data.geom_xmat[g].reshape(3, 3), model.geom_size[g]
        if model.geom_type[g] == 6:        # box: the corners of its XZ face (axis 1 across y)
            if abs(c[1] - y) > size[1] * abs(R[1, 1]) + 1e-9:
                continue
            ex, ez = R[:, 0] * size[0], R[:, 2] * size[2]
            corners = [c + sx * ex + sz * ez for sx, sz in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
        elif model.geom_type[g] == 3:      # capsule along its z axis, radius size[0], half-length size[1]
            if abs(c[1] - y) > size[0]:
                continue
            a = R[:, 2] * size[1]
            nrm = np.array([-R[2, 2], 0.0, R[0, 2]])
            nrm = nrm / (np.linalg.norm(nrm) or 1.0) * size[0]
            corners = [c - a - nrm, c + a - nrm, c + a + nrm, c - a + nrm]
        else:
            continue
        for k in range(4):
            p, q = corners[k], corners[(k + 1) % 4]
            segs.append((p[0], p[2], q[0], q[2]))
    return np.array(segs, dtype=float).reshape(-1, 4)


def lidar_scan(model: LidarModel, pile, rng: np.random.Generator, clutter: DrawPoint | None = None,
               occluders: np.ndarray | None = None):
    """(ranges (n,) float64 with inf for no return, angle_min, angle_increment) of one scan of
    the current pile. `clutter` adds the draw point's ceiling and drawbell (and, for beams
    leaving the scan plane, its side walls); `occluders` (m, 4) more XZ segments, e.g.
    machine_segments of the simulated machine. Ranges outside [range_min, range_max] are inf."""
    T = model.T_pile_sensor
    o = T[:3, 3]
    d = model.beam_directions()
    y_plane = float(o[1])
    parts = [pile_segments(pile, y_plane, model.back_wall_gap)]
    if clutter is not None:
        parts.append(draw_point_segments(clutter))
    if occluders is not None and len(occluders):
        parts.append(np.asarray(occluders, dtype=float).reshape(-1, 4))
    # the scene is the XZ profile extruded across y: a beam's XZ components meet it at the same t
    t = cast_rays(float(o[0]), float(o[2]), d[:, 0], d[:, 2], np.vstack(parts))
    if clutter is not None:
        with np.errstate(divide="ignore", invalid="ignore"):
            wall = (np.sign(d[:, 1]) * clutter.wall_y - o[1]) / d[:, 1]
        t = np.minimum(t, np.where(np.isfinite(wall) & (wall > 0), wall, np.inf))
    r = t + rng.normal(0.0, model.noise, model.n) if model.noise > 0 else t.copy()
    if model.outliers > 0:
        out = rng.random(model.n) < model.outliers
        r[out] = rng.uniform(model.range_min, model.range_max, int(out.sum()))
    r[~np.isfinite(r) | (r > model.range_max) | (r < model.range_min)] = np.inf
    return r, model.angle_min, model.angle_increment


# ---------------------------------------------------------------------------------- markers
def pile_surfaces(pile, back_wall_gap: float = 0.3) -> list[np.ndarray]:
    """One (n, 3) polyline per slice of the pile (its current surface, pile_profile at the
    slice's y): the pile surface as a stack of line strips."""
    out = []
    for y in pile.y_centers:
        p = pile_profile(pile, float(y), back_wall_gap)
        out.append(np.column_stack([p[:, 0], np.full(len(p), float(y)), p[:, 1]]))
    return out


def fee_arrow(tip_xyz, force, scale: float = 0.0005, min_force: float = 1.0) -> np.ndarray | None:
    """(2, 3) start and end of the FEE force arrow: from the bucket tip along the pile's force
    on the bucket (LhdSimulator.last_fee.force, N), `scale` m per N (default 0.5 m per kN).
    None when the force is below min_force (the bucket is out of the pile)."""
    f = np.asarray(force, dtype=float).reshape(3)
    tip = np.asarray(tip_xyz, dtype=float).reshape(3)
    if not (np.isfinite(f).all() and np.isfinite(tip).all()) or np.linalg.norm(f) < min_force:
        return None
    return np.vstack([tip, tip + scale * f])


def imu_specific_force(true_quat, a_world, g: float = 9.81) -> np.ndarray:
    """What an IMU's accelerometer on the rear frame measures (m/s^2, its own axes = base_link's):
    the specific force R^T (a + (0, 0, g)), a the frame's acceleration in the world (m/s^2) and R
    its orientation (w, x, y, z). At rest on a level floor: (0, 0, +g), as sensor_msgs/Imu has it."""
    w, x, y, z = (float(c) for c in true_quat)
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                  [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                  [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    return R.T @ (np.asarray(a_world, dtype=float) + np.array([0.0, 0.0, g]))


def imu_orientation(true_quat, roll_noise: float, pitch_noise: float) -> tuple[float, float, float, float]:
    """What an IMU on the rear frame reports (w, x, y, z): the machine's true orientation turned,
    in its own frame, by a small roll and pitch error (rad): q_true * q(Rx(roll) Ry(pitch))."""
    a, b = roll_noise / 2.0, pitch_noise / 2.0
    nw, nx, ny, nz = (math.cos(a) * math.cos(b), math.sin(a) * math.cos(b), math.cos(a) * math.sin(b),
                      math.sin(a) * math.sin(b))
    w, x, y, z = (float(c) for c in true_quat)
    return (w * nw - x * nx - y * ny - z * nz, w * nx + x * nw + y * nz - z * ny,
            w * ny - x * nz + y * nw + z * nx, w * nz + x * ny - y * nx + z * nw)
