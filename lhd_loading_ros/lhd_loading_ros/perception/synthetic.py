"""Synthetic sensor data with known ground truth, for tests and benchmarks: a real ArUco
marker warped into a pinhole camera, and LiDAR scans of a pile with floor and back wall."""
from __future__ import annotations

import math

import cv2
import numpy as np

from lhd_loading_ros.perception.aruco import dictionary, project
from lhd_loading_ros.perception.geometry import apply, transform

# Camera 1.5 m above the floor looking straight down; image right = -y, image down = -x.
CAMERA_RPY = (math.pi, 0.0, -math.pi / 2)


def intrinsics(width: int, height: int, f: float | None = None) -> np.ndarray:
    f = f if f is not None else 0.94 * width
    return np.array([[f, 0.0, width / 2.0], [0.0, f, height / 2.0], [0.0, 0.0, 1.0]])


def marker_texture(dict_name: str, marker_id: int, px: int = 200, border: int = 50) -> np.ndarray:
    img = cv2.aruco.generateImageMarker(dictionary(dict_name), marker_id, px)
    return cv2.copyMakeBorder(img, border, border, border, border, cv2.BORDER_CONSTANT, value=255)


def render(K: np.ndarray, width: int, height: int, T_cam_marker: np.ndarray, texture: np.ndarray, marker_size: float,
           rng: np.random.Generator, noise: float = 4.0, blur: int = 3, occlusion: float = 0.0,
           background: np.ndarray | None = None, marker_px: int = 200) -> np.ndarray:
    """Grayscale image of the marker (black square of side marker_size, white quiet zone)
    at pose T_cam_marker, on a textured background, with sensor noise, blur and an optional
    occluding bar covering `occlusion` of the marker's width."""
    h = marker_size * texture.shape[0] / marker_px / 2.0  # the texture includes the white quiet zone
    obj = np.array([[-h, h, 0], [h, h, 0], [h, -h, 0], [-h, -h, 0]])
    uv = project(K, T_cam_marker, obj).astype(np.float32)
    src = np.array([[0, 0], [texture.shape[1], 0], [texture.shape[1], texture.shape[0]], [0, texture.shape[0]]],
                   dtype=np.float32)
    H = cv2.getPerspectiveTransform(src, uv)
    if background is None:
        background = (90 + 40 * rng.random((height, width))).astype(np.uint8)
        background = cv2.GaussianBlur(background, (0, 0), 3)
    warped = cv2.warpPerspective(texture, H, (width, height), flags=cv2.INTER_LINEAR)
    mask = cv2.warpPerspective(np.full_like(texture, 255), H, (width, height), flags=cv2.INTER_LINEAR)
    img = np.where(mask > 127, warped, background).astype(np.float64)
    if occlusion > 0:
        c = uv.mean(axis=0)
        w = np.linalg.norm(uv[1] - uv[0])
        x0 = int(c[0] - w / 2)
        cv2.rectangle(img, (x0, int(c[1] - w)), (x0 + int(occlusion * w), int(c[1] + w)), 60, thickness=-1)
    if blur:
        img = cv2.GaussianBlur(img, (0, 0), blur / 3.0)
    img += rng.normal(0.0, noise, img.shape)
    return np.clip(img, 0, 255).astype(np.uint8)


def drive_poses(t: np.ndarray, x0: float, speed: float, height: float = 0.35) -> list[np.ndarray]:
    """Marker poses (in the pile frame) on the machine's roof, facing up, driving along +x."""
    return [transform((x0 + speed * ti, 0.0, height), (0.0, 0.0, 0.0)) for ti in t]


# ---------------------------------------------------------------- LiDAR
def pile_profile_hits(origin: np.ndarray, dirs: np.ndarray, alpha: float, toe_x: float, h: float,
                      back_x: float) -> np.ndarray:
    """Range along each ray (XZ plane of the pile frame) to the first surface: floor (z = 0),
    face (rising at alpha from the toe), top (z = h) and back wall (x = back_x)."""
    ox, oz = origin[0], origin[2]
    dx, dz = dirs[:, 0], dirs[:, 2]
    inf = np.full(len(dirs), np.inf)
    top_x = toe_x + h / math.tan(alpha)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_floor = np.where(dz < 0, -oz / dz, inf)
        xf = ox + t_floor * dx
        t_floor = np.where((xf <= toe_x) & (t_floor > 0), t_floor, inf)
        ta = math.tan(alpha)
        t_face = (ta * (ox - toe_x) - oz) / (dz - ta * dx)
        xfa = ox + t_face * dx
        t_face = np.where((t_face > 0) & (xfa >= toe_x) & (xfa <= top_x), t_face, inf)
        t_top = np.where(dz < 0, (h - oz) / dz, inf)
        xt = ox + t_top * dx
        t_top = np.where((t_top > 0) & (xt >= top_x) & (xt <= back_x), t_top, inf)
        t_wall = np.where(dx > 0, (back_x - ox) / dx, inf)
        zw = oz + t_wall * dz
        t_wall = np.where((t_wall > 0) & (zw >= 0), t_wall, inf)
    return np.minimum.reduce([t_floor, t_face, t_top, t_wall])


def synthetic_scan(alpha: float, rng: np.random.Generator, sensor_xyz=(0.6, 0.0, 1.6), toe_x: float = 0.0,
                   h: float = 0.68, back_x: float | None = None, n: int = 720, angle_min: float = -math.radians(170),
                   angle_max: float = -math.radians(10), noise: float = 0.01, outliers: float = 0.1,
                   range_max: float = 8.0):
    """(ranges, angle_min, angle_increment, sensor_rpy) of a vertical LaserScan over the pile:
    the scanner's XY plane is the pile's XZ plane (roll = 90 deg)."""
    back_x = back_x if back_x is not None else toe_x + h / math.tan(alpha) + 0.3
    rpy = (math.pi / 2, 0.0, 0.0)
    T = transform(sensor_xyz, rpy)
    ang = np.linspace(angle_min, angle_max, n)
    dirs_s = np.column_stack([np.cos(ang), np.sin(ang), np.zeros(n)])
    dirs = dirs_s @ T[:3, :3].T
    r = pile_profile_hits(np.asarray(sensor_xyz, float), dirs, alpha, toe_x, h, back_x)
    r = r + rng.normal(0.0, noise, n)
    out = rng.random(n) < outliers
    r[out] = rng.uniform(0.2, range_max, out.sum())
    r[~np.isfinite(r)] = np.inf
    inc = (angle_max - angle_min) / (n - 1)
    return r, angle_min, inc, rpy


def scan_points_pile(ranges, angle_min, inc, sensor_xyz, sensor_rpy):
    from lhd_loading_ros.perception.slope import scan_to_points
    return apply(transform(sensor_xyz, sensor_rpy), scan_to_points(angle_min, inc, ranges, 0.05, 30.0))
