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


class NoSlope(ValueError):
    """No slope from this scan; the message says why."""


class TooFewPoints(NoSlope):
    """No pile face in the points."""


class SlopeOutOfRange(NoSlope):
    """A face was found, but its slope is outside the configured physical range."""


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


# RANSAC looks for faces over a wider band than the accepted range, so that a face found
# outside the range is reported as such ("slope 62 deg outside [5, 50]") instead of as "no pile";
# the floor and pile top (0 deg) and walls (90 deg) stay outside the band.
SEARCH_MIN, SEARCH_MAX = math.radians(2.0), math.radians(75.0)
FOOT_MAX_Z = 0.15    # m: the face's lowest point must be this close to the floor (the toe is in view)
MAX_GAP = 0.15       # m along x: a larger gap between points on a line ends a contiguous run
MAX_CANDIDATES = 20  # lines (most inliers first) checked for a face before giving up


def fit_slope(pts_pile: np.ndarray, rng: np.random.Generator, floor_z: float = 0.03, min_points: int = 30,
              iterations: int = 200, threshold: float = 0.02, slope_min: float = math.radians(5),
              slope_max: float = math.radians(50), max_z: float = 1.5, max_abs_y: float = 0.3) -> SlopeFit:
    """Robust fit of the pile face in the XZ plane of the pile frame.

    Only points between the floor and `max_z` (below the ceiling, the brow and the drawbell)
    and within `max_abs_y` of the scan plane (not the drift's side walls) take part. RANSAC
    proposes lines; the face is the line with the most inliers whose lowest contiguous run of
    inliers (gaps < MAX_GAP) holds `min_points` and starts at the floor (below FOOT_MAX_Z), so a
    heaped bucket, the machine or a slope in the roof cannot pass for the face. Least squares on
    that run, twice. A face outside [slope_min, slope_max] raises SlopeOutOfRange; no face
    raises TooFewPoints: never a guess."""
    keep = (pts_pile[:, 2] > floor_z) & (pts_pile[:, 2] < max_z) & (np.abs(pts_pile[:, 1]) <= max_abs_y)
    p = pts_pile[keep]
    if len(p) < min_points:
        raise TooFewPoints(f"{len(p)} points between the floor and {max_z:g} m; need at least {min_points}")
    x, z = p[:, 0], p[:, 2]
    n = len(p)
    i = rng.integers(0, n, size=(iterations, 2))
    dx = x[i[:, 1]] - x[i[:, 0]]
    dz = z[i[:, 1]] - z[i[:, 0]]
    with np.errstate(divide="ignore", invalid="ignore"):
        a = dz / dx
    ok = np.isfinite(a) & (a >= math.tan(SEARCH_MIN)) & (a <= math.tan(SEARCH_MAX))
    if not ok.any():
        raise TooFewPoints("no pair of points spans a plausible pile face")
    a = a[ok]
    b = z[i[ok, 0]] - a * x[i[ok, 0]]
    # inliers of all candidate lines: perpendicular distance |a x - z + b| / sqrt(1 + a^2) below
    # the threshold, compared without dividing the whole matrix; float32 is ample for counting
    # (metres against a centimetre band) and halves the memory traffic
    band = (threshold * np.sqrt(1.0 + a * a)).astype(np.float32)
    r = a.astype(np.float32)[:, None] * x.astype(np.float32)[None, :]
    r += b.astype(np.float32)[:, None]
    r -= z.astype(np.float32)[None, :]
    np.abs(r, out=r)
    counts = np.count_nonzero(r < band[:, None], axis=1)
    best = int(counts.max())
    run = None
    for k in np.argsort(-counts, kind="stable")[:MAX_CANDIDATES]:
        if counts[k] < min_points:
            break
        run = _face_run(x, z, r[k] < band[k], min_points)
        if run is not None:
            break
    if run is None:
        if best < min_points:
            raise TooFewPoints(f"only {best} points on the best face line; need at least {min_points}")
        raise TooFewPoints(f"no line of {math.degrees(SEARCH_MIN):.0f}-{math.degrees(SEARCH_MAX):.0f} deg with "
                           f"{min_points} contiguous points rises from the floor (below {FOOT_MAX_Z} m)")
    inl = run
    lo, hi = x[inl].min() - MAX_GAP, x[inl].max() + MAX_GAP
    span = (x >= lo) & (x <= hi)
    # least squares on the run, then once more with the refined line (within the run's extent)
    for _ in range(2):
        A = np.column_stack([x[inl], np.ones(inl.sum())])
        (sa, sb), *_ = np.linalg.lstsq(A, z[inl], rcond=None)
        dist = np.abs(sa * x - z + sb) / math.sqrt(1 + sa * sa)
        new = (dist < threshold) & span
        if new.sum() >= min_points:
            inl = new
    alpha = math.atan(sa)
    if not slope_min <= alpha <= slope_max:
        raise SlopeOutOfRange(f"slope {math.degrees(alpha):.1f} deg outside "
                              f"[{math.degrees(slope_min):g}, {math.degrees(slope_max):g}]")
    res = float(np.sqrt(np.mean(((sa * x[inl] - z[inl] + sb) ** 2) / (1 + sa * sa))))
    return SlopeFit(alpha=alpha, toe_x=float(-sb / sa), residual=res, inliers=int(inl.sum()),
                    slope=float(sa), intercept=float(sb))


def _face_run(x: np.ndarray, z: np.ndarray, inl: np.ndarray, min_points: int) -> np.ndarray | None:
    """Mask of the lowest contiguous run of a line's inliers if it is a face (at least
    `min_points` points, its foot at the floor), else None."""
    idx = np.flatnonzero(inl)
    idx = idx[np.argsort(x[idx], kind="stable")]
    bounds = np.concatenate(([0], np.flatnonzero(np.diff(x[idx]) > MAX_GAP) + 1, [len(idx)]))
    long_runs = np.flatnonzero(np.diff(bounds) >= min_points)
    if len(long_runs):                  # the lowest long run, from the toe side up the face
        seg = idx[bounds[long_runs[0]]:bounds[long_runs[0] + 1]]
        if z[seg].min() <= FOOT_MAX_Z:
            m = np.zeros(len(x), bool)
            m[seg] = True
            return m
    return None
