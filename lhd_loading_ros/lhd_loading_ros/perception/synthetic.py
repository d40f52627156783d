"""Synthetic sensor data with known ground truth, for tests and benchmarks: a real ArUco
marker warped into a pinhole camera, and LiDAR scans of a pile with floor and back wall, optionally
in a draw point (ceiling, brow, side walls, the machine itself)."""
from __future__ import annotations

import math
from dataclasses import dataclass

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


SUPERSAMPLE = 4   # sub-pixels per pixel side where the marker is drawn (area integration; 8 is no smoother)


def render(K: np.ndarray, width: int, height: int, T_cam_marker: np.ndarray, texture: np.ndarray, marker_size: float,
           rng: np.random.Generator, noise: float = 4.0, blur: int = 3, occlusion: float = 0.0,
           background: np.ndarray | None = None, marker_px: int = 200, supersample: int = SUPERSAMPLE,
           noise_bank: np.ndarray | None = None) -> np.ndarray:
    """Grayscale image of the marker (black square of side marker_size, white quiet zone)
    at pose T_cam_marker, on a textured background, with sensor noise, blur and an optional
    occluding bar covering `occlusion` of the marker's width.

    A camera pixel integrates the light over its area. Sampling the texture once per pixel (a
    plain warp) puts every edge on the pixel grid: the corners then move in whole-pixel steps
    and the ArUco pose carries a sawtooth error with a one-pixel period (1 mm sd at 1.6 m with
    the twin's camera; test_perception.py measures it). So the marker's bounding box is drawn on
    a grid of `supersample` x `supersample` sub-pixels per pixel (texture warp, anti-aliased
    outline over the background) and averaged back to pixels (INTER_AREA: the box filter of
    the pixel's area). Pixel centres are at integer coordinates (OpenCV's and the pinhole
    model's convention); texel centres too, so the texture's outer edges are at -0.5 and n-0.5.

    `noise_bank` (optional, (k, >= height, >= width) standard normal float32): the sensor noise
    is a random crop of a random one of these fields instead of fresh draws (a real-time twin
    saves 4 ms a frame; the noise keeps its distribution and stays white within a frame)."""
    h = marker_size * texture.shape[0] / marker_px / 2.0  # the texture includes the white quiet zone
    obj = np.array([[-h, h, 0], [h, h, 0], [h, -h, 0], [-h, -h, 0]])
    uv = project(K, T_cam_marker, obj)
    if background is None:
        background = (90 + 40 * rng.random((height, width))).astype(np.uint8)
        background = cv2.GaussianBlur(background, (0, 0), 3)
    img = background.astype(np.float32)
    x0, x1 = max(0, int(np.floor(uv[:, 0].min())) - 2), min(width, int(np.ceil(uv[:, 0].max())) + 3)
    y0, y1 = max(0, int(np.floor(uv[:, 1].min())) - 2), min(height, int(np.ceil(uv[:, 1].max())) + 3)
    if x1 > x0 and y1 > y0 and np.isfinite(uv).all():
        S = int(supersample)
        n, m = texture.shape[1], texture.shape[0]
        src = np.array([[-0.5, -0.5], [n - 0.5, -0.5], [n - 0.5, m - 0.5], [-0.5, m - 0.5]], dtype=np.float32)
        # sub-pixel i of ROI pixel p is centred at image coordinate x0 + p - 0.5 + (i + 0.5) / S
        dst = ((uv - [x0, y0] + 0.5) * S - 0.5).astype(np.float32)
        H = cv2.getPerspectiveTransform(src, dst)
        size = ((x1 - x0) * S, (y1 - y0) * S)
        warped = cv2.warpPerspective(texture.astype(np.float32), H, size, flags=cv2.INTER_LINEAR,
                                     borderMode=cv2.BORDER_REPLICATE)
        cover = np.zeros(size[::-1], np.float32)
        cv2.fillConvexPoly(cover, np.round(dst * 16).astype(np.int32), 1.0, lineType=cv2.LINE_AA, shift=4)
        under = cv2.resize(img[y0:y1, x0:x1], size, interpolation=cv2.INTER_NEAREST)
        img[y0:y1, x0:x1] = cv2.resize(cover * warped + (1.0 - cover) * under, (x1 - x0, y1 - y0),
                                       interpolation=cv2.INTER_AREA)
    if occlusion > 0:
        c = uv.mean(axis=0)
        w = np.linalg.norm(uv[1] - uv[0])
        x0 = int(c[0] - w / 2)
        cv2.rectangle(img, (x0, int(c[1] - w)), (x0 + int(occlusion * w), int(c[1] + w)), 60, thickness=-1)
    if blur:
        img = cv2.GaussianBlur(img, (0, 0), blur / 3.0)
    if noise and noise_bank is not None:
        k = int(rng.integers(noise_bank.shape[0]))
        dy = int(rng.integers(noise_bank.shape[1] - height + 1))
        dx = int(rng.integers(noise_bank.shape[2] - width + 1))
        img += noise_bank[k, dy:dy + height, dx:dx + width] * np.float32(noise)
    elif noise:
        img += rng.standard_normal(img.shape, dtype=np.float32) * np.float32(noise)
    return np.clip(img, 0, 255).astype(np.uint8)


def drive_poses(t: np.ndarray, x0: float, speed: float, height: float = 0.35) -> list[np.ndarray]:
    """Marker poses (in the pile frame) on the machine's roof, facing up, driving along +x."""
    return [transform((x0 + speed * ti, 0.0, height), (0.0, 0.0, 0.0)) for ti in t]


# ---------------------------------------------------------------- LiDAR
FAR = 50.0   # m: "unbounded" ends of floor, walls and ceiling


@dataclass
class DrawPoint:
    """What else a LiDAR over a draw point sees besides floor, face, pile top and back wall
    (5:1 scale): the drift's ceiling at `ceiling_z` up to the brow at `brow_x`, where the
    drawbell's front wall rises at `drawbell_deg` over the pile (a line of plausible pile slope,
    well above the crest); the drift's side walls at y = +-`wall_y` (only a 3-D scan reaches
    them); and the LHD itself in front of the toe: its bucket lip `bucket_gap` before the toe,
    a load heaped in the bucket at its angle of repose, the machine's body behind."""
    ceiling_z: float = 2.0
    brow_x: float = 0.2
    drawbell_deg: float = 45.0
    wall_y: float = 0.45
    machine: bool = True
    bucket_gap: float = 0.05
    heap_deg: float = 35.0


def scene_segments(alpha: float, toe_x: float, h: float, back_x: float, clutter: DrawPoint | None) -> np.ndarray:
    """The XZ profile of the scene as segments (m, 4): x0, z0, x1, z1."""
    top_x = toe_x + h / math.tan(alpha)
    segs = [(-FAR, 0.0, toe_x, 0.0), (toe_x, 0.0, top_x, h), (top_x, h, back_x, h), (back_x, h, back_x, FAR)]
    if clutter is not None:
        c = clutter
        rise = FAR - c.ceiling_z
        segs += [(-FAR, c.ceiling_z, c.brow_x, c.ceiling_z),
                 (c.brow_x, c.ceiling_z, c.brow_x + rise / math.tan(math.radians(c.drawbell_deg)), FAR)]
        if c.machine:
            lip = toe_x - c.bucket_gap
            back = lip - 0.36                       # bucket: lip on the floor, 0.36 m deep, 0.22 m high
            th = math.tan(math.radians(c.heap_deg))
            peak_x = (lip + back) / 2.0
            segs += [(lip, 0.02, back, 0.02), (back, 0.02, back, 0.24),
                     (back, 0.24, peak_x, 0.24 + th * (peak_x - back)),            # the load, heaped
                     (peak_x, 0.24 + th * (peak_x - back), lip, 0.02 + 0.22 * 0.0),
                     (back - 0.25, 0.08, back - 0.25, 0.35), (back - 0.25, 0.35, back - 1.2, 0.35)]  # body
    return np.array(segs, dtype=float)


def cast_rays(ox: float, oz: float, dx: np.ndarray, dz: np.ndarray, segs: np.ndarray) -> np.ndarray:
    """Ray parameter t of the first segment hit by each ray o + t (dx, dz) (inf: none)."""
    ex, ez = segs[:, 2] - segs[:, 0], segs[:, 3] - segs[:, 1]
    wx, wz = segs[:, 0] - ox, segs[:, 1] - oz
    with np.errstate(divide="ignore", invalid="ignore"):
        den = dx[:, None] * ez[None, :] - dz[:, None] * ex[None, :]
        t = (wx * ez - wz * ex)[None, :] / den
        s = (wx[None, :] * dz[:, None] - wz[None, :] * dx[:, None]) / den
        t = np.where((np.abs(den) > 1e-12) & (t > 1e-9) & (s >= 0.0) & (s <= 1.0), t, np.inf)
    return t.min(axis=1)


def synthetic_scan(alpha: float, rng: np.random.Generator, sensor_xyz=(0.6, 0.0, 1.6), toe_x: float = 0.0,
                   h: float = 0.68, back_x: float | None = None, n: int = 720, angle_min: float = -math.radians(170),
                   angle_max: float = -math.radians(10), noise: float = 0.01, outliers: float = 0.1,
                   range_max: float = 8.0, clutter: DrawPoint | None = None):
    """(ranges, angle_min, angle_increment, sensor_rpy) of a vertical LaserScan over the pile:
    the scanner's XY plane is the pile's XZ plane (roll = 90 deg). `clutter` adds the draw
    point around the pile (widen the angles to see the ceiling)."""
    back_x = back_x if back_x is not None else toe_x + h / math.tan(alpha) + 0.3
    rpy = (math.pi / 2, 0.0, 0.0)
    T = transform(sensor_xyz, rpy)
    ang = np.linspace(angle_min, angle_max, n)
    dirs = np.column_stack([np.cos(ang), np.sin(ang), np.zeros(n)]) @ T[:3, :3].T
    r = cast_rays(sensor_xyz[0], sensor_xyz[2], dirs[:, 0], dirs[:, 2], scene_segments(alpha, toe_x, h, back_x, clutter))
    r = r + rng.normal(0.0, noise, n)
    out = rng.random(n) < outliers
    r[out] = rng.uniform(0.2, range_max, out.sum())
    r[~np.isfinite(r) | (r > range_max)] = np.inf
    inc = (angle_max - angle_min) / (n - 1)
    return r, angle_min, inc, rpy


def synthetic_cloud(alpha: float, rng: np.random.Generator, sensor_xyz=(0.6, 0.0, 1.6), toe_x: float = 0.0,
                    h: float = 0.68, clutter: DrawPoint | None = None, yaws_deg=(-30, -15, 0, 15, 30),
                    n: int = 720, noise: float = 0.01, range_max: float = 8.0) -> np.ndarray:
    """Points (n_planes * n, 3) in the frame of the sensor of `synthetic_scan`: vertical scan
    planes fanned in yaw about the sensor (a 3-D LiDAR's view), the pile's profile extruded
    across y and, with clutter, the drift's side walls at y = +-wall_y."""
    back_x = toe_x + h / math.tan(alpha) + 0.3
    segs = scene_segments(alpha, toe_x, h, back_x, clutter)
    T = transform(sensor_xyz, (math.pi / 2, 0.0, 0.0))
    ang = np.linspace(-math.pi, math.pi, n, endpoint=False)
    out = []
    for yaw in np.radians(yaws_deg):
        d = np.column_stack([np.cos(ang) * math.cos(yaw), np.cos(ang) * math.sin(yaw), np.sin(ang)])  # pile frame
        t = cast_rays(sensor_xyz[0], sensor_xyz[2], d[:, 0], d[:, 2], segs)
        if clutter is not None:
            with np.errstate(divide="ignore", invalid="ignore"):
                wall = (np.sign(d[:, 1]) * clutter.wall_y - sensor_xyz[1]) / d[:, 1]
            t = np.minimum(t, np.where(wall > 0, wall, np.inf))
        t = t + rng.normal(0.0, noise, n)
        ok = np.isfinite(t) & (t < range_max)
        out.append(apply(np.linalg.inv(T), np.asarray(sensor_xyz) + t[ok, None] * d[ok]))
    return np.concatenate(out)


def scan_points_pile(ranges, angle_min, inc, sensor_xyz, sensor_rpy):
    from lhd_loading_ros.perception.slope import scan_to_points
    return apply(transform(sensor_xyz, sensor_rpy), scan_to_points(angle_min, inc, ranges, 0.05, 30.0))
