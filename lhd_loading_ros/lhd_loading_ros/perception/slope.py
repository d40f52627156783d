"""Pile slope from LiDAR points, without ROS.

Points (LaserScan in a vertical plane over the pile, or PointCloud2) are moved into the pile
frame with the sensor's pose, floor points are dropped, and a line z = a x + b is fitted in
the XZ plane by RANSAC restricted to plausible face slopes (so neither the floor nor the back
wall can win), then refined by least squares on the inliers. alpha = atan(a); the toe is
where the line meets the floor (x = -b / a).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

PC2_FLOAT32 = 7  # sensor_msgs/PointField.FLOAT32
PC2_FLOAT64 = 8


class TooFewPoints(ValueError):
    pass


def scan_to_points(angle_min: float, angle_increment: float, ranges, range_min: float, range_max: float) -> np.ndarray:
    """LaserScan -> (n, 3) points in the scanner frame (invalid ranges dropped)."""
    r = np.asarray(ranges, dtype=np.float64)
    a = angle_min + angle_increment * np.arange(r.size)
    ok = np.isfinite(r) & (r >= range_min) & (r <= range_max)
    r, a = r[ok], a[ok]
    return np.column_stack([r * np.cos(a), r * np.sin(a), np.zeros_like(r)])


def cloud_to_points(fields, point_step: int, row_step: int, width: int, height: int, data: bytes,
                    is_bigendian: bool) -> np.ndarray:
    """PointCloud2 -> (n, 3) float64 x, y, z (sensor_msgs_py is not available here)."""
    offs = {}
    for f in fields:
        if f.name in ("x", "y", "z"):
            if f.datatype not in (PC2_FLOAT32, PC2_FLOAT64):
                raise ValueError(f"PointCloud2 field {f.name} has datatype {f.datatype}; expected FLOAT32 (7) or FLOAT64 (8)")
            offs[f.name] = (f.offset, f.datatype)
    if set(offs) != {"x", "y", "z"}:
        raise ValueError(f"PointCloud2 needs fields x, y, z; got {[f.name for f in fields]}")
    n = width * height
    if len(data) < row_step * height or point_step * width > row_step:
        raise ValueError("PointCloud2 data is shorter than its declared size")
    end = ">" if is_bigendian else "<"
    raw = np.frombuffer(data, dtype=np.uint8, count=row_step * height).reshape(height, row_step)[:, : point_step * width]
    raw = np.ascontiguousarray(raw).reshape(n, point_step)
    cols = []
    for name in ("x", "y", "z"):
        off, dt = offs[name]
        size = 4 if dt == PC2_FLOAT32 else 8
        typ = np.dtype(f"{end}f{size}")
        cols.append(raw[:, off:off + size].copy().view(typ).ravel().astype(np.float64))
    pts = np.column_stack(cols)
    return pts[np.all(np.isfinite(pts), axis=1)]


@dataclass
class SlopeFit:
    alpha: float        # rad
    toe_x: float        # m, where the face meets the floor (pile frame)
    residual: float     # m, RMS distance of the inliers to the line
    inliers: int
    slope: float
    intercept: float


def fit_slope(pts_pile: np.ndarray, rng: np.random.Generator, floor_z: float = 0.03, min_points: int = 30,
              iterations: int = 200, threshold: float = 0.02, slope_min: float = math.radians(5),
              slope_max: float = math.radians(50)) -> SlopeFit:
    """Robust fit of the pile face in the XZ plane of the pile frame."""
    p = pts_pile[pts_pile[:, 2] > floor_z]
    if len(p) < min_points:
        raise TooFewPoints(f"{len(p)} points above the floor; need at least {min_points}")
    x, z = p[:, 0], p[:, 2]
    tmin, tmax = math.tan(slope_min), math.tan(slope_max)
    best_count = -1
    n = len(p)
    i = rng.integers(0, n, size=(iterations, 2))
    dx = x[i[:, 1]] - x[i[:, 0]]
    dz = z[i[:, 1]] - z[i[:, 0]]
    with np.errstate(divide="ignore", invalid="ignore"):
        a = dz / dx
    ok = np.isfinite(a) & (a >= tmin) & (a <= tmax)
    if not ok.any():
        raise TooFewPoints("no pair of points spans a plausible pile face")
    a = a[ok]
    b = z[i[ok, 0]] - a * x[i[ok, 0]]
    # perpendicular distances of all points to all candidate lines, in blocks
    norm = np.sqrt(1.0 + a * a)
    d = np.abs(a[:, None] * x[None, :] - z[None, :] + b[:, None]) / norm[:, None]
    counts = (d < threshold).sum(axis=1)
    k = int(np.argmax(counts))
    best_count = int(counts[k])
    if best_count < min_points:
        raise TooFewPoints(f"only {best_count} points on the best face line; need at least {min_points}")
    inl = d[k] < threshold
    # least squares on the inliers, then once more with the refined line
    for _ in range(2):
        A = np.column_stack([x[inl], np.ones(inl.sum())])
        (sa, sb), *_ = np.linalg.lstsq(A, z[inl], rcond=None)
        dist = np.abs(sa * x - z + sb) / math.sqrt(1 + sa * sa)
        new = dist < threshold
        if new.sum() >= min_points:
            inl = new
    res = float(np.sqrt(np.mean(((sa * x[inl] - z[inl] + sb) ** 2) / (1 + sa * sa))))
    return SlopeFit(alpha=math.atan(sa), toe_x=float(-sb / sa), residual=res, inliers=int(inl.sum()),
                    slope=float(sa), intercept=float(sb))
