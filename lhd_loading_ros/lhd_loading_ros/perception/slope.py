"""Pile slope from LiDAR points, without ROS.

Points (LaserScan in a vertical plane over the pile, or PointCloud2) are moved into the pile
frame with the sensor's pose, floor points are dropped, and a line z = a x + b is fitted in
the XZ plane by RANSAC restricted to plausible face slopes (so neither the floor nor the back
wall can win), then refined over the whole face at its own roughness (refine_face: the profile
floor - face - crest, z = clip(a x + b, 0, h), by Tukey-weighted least squares). alpha = atan(a);
the toe is where the line meets the floor (x = -b / a).

Why the second stage (2026-11-28, docs/perception.md "Rough faces"): RANSAC's inlier band (2 cm,
twice the range noise) fits a plane face, but on a face with bumps of a rock's size (3 cm sd) each
scan's inliers are a different short run of the face, and alpha jumped by 2-4 deg between scans of
a pile that does not move. The whole-face fit takes every point the profile model explains, so
successive scans agree within 0.1-1 deg and the slope is the face's, not a bump's.
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


def scan_problem(angle_min: float, angle_max: float, angle_increment: float, n: int, range_min: float,
                 range_max: float, n_intensities: int = 0) -> str | None:
    """Why a LaserScan's header cannot place its beams, or None. Beam i lies at angle_min + i *
    angle_increment, and the last one must be angle_max (REP: sensor_msgs/LaserScan), within one
    increment (drivers differ by one on whether angle_max is the last beam's): a header that
    disagrees is a misconfigured driver, and fitting it anyway tilts the slope (an increment 2 %
    off turned a 20 deg pile into 21.8 deg, published as valid: a review's fault injection).
    `n_intensities`: the message's intensities, which must be empty or one per range
    (sensor_msgs/LaserScan); another count says the driver lost or added beams in one of the
    arrays, so which angle a range belongs to is not known either."""
    vals = {"angle_min": angle_min, "angle_max": angle_max, "angle_increment": angle_increment,
            "range_min": range_min, "range_max": range_max}
    # range_max may be +inf: pointcloud_to_laserscan's default (DBL_MAX, inf in the float32 field)
    bad = [k for k, v in vals.items() if not (math.isfinite(v) or (k == "range_max" and v == math.inf))]
    if bad:
        return f"LaserScan {', '.join(f'{k} = {vals[k]!r}' for k in bad)}: expected finite numbers"
    if n < 2:
        return f"LaserScan with {n} ranges: expected a scan of at least 2 beams"
    if n_intensities not in (0, n):
        return (f"LaserScan with {n} ranges but {n_intensities} intensities: expected one intensity per range, "
                "or none (a driver that lost or added beams in one of the arrays)")
    if angle_increment == 0.0:
        return "LaserScan angle_increment = 0: expected the angle between beams (rad)"
    last = angle_min + (n - 1) * angle_increment
    if abs(last - angle_max) > 1.01 * abs(angle_increment) + 1e-6:
        return (f"LaserScan header disagrees with itself: angle_min {angle_min:.5f} + ({n} - 1) x angle_increment "
                f"{angle_increment:.6f} = {last:.5f} rad, but angle_max = {angle_max:.5f} rad; expected the last beam "
                f"at angle_max (check the driver's angle_increment and the number of ranges)")
    if not 0.0 <= range_min < range_max:
        return f"LaserScan range_min {range_min:g} / range_max {range_max:g} m: expected 0 <= range_min < range_max"
    return None


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
MAX_FIT_POINTS = 12000  # points of the band a fit takes at most (every k-th of a denser cloud): a scan
                        # line has 720-1440; a 3-D cloud can put 100,000 and more in the band


def fit_slope(pts_pile: np.ndarray, rng: np.random.Generator, floor_z: float = 0.03, min_points: int = 30,
              iterations: int = 200, threshold: float = 0.02, slope_min: float = math.radians(5),
              slope_max: float = math.radians(50), max_z: float = 1.5, max_abs_y: float = 0.3) -> SlopeFit:
    """Robust fit of the pile face in the XZ plane of the pile frame.

    Only points between the floor and `max_z` (below the ceiling, the brow and the drawbell)
    and within `max_abs_y` of the scan plane (not the drift's side walls) take part. RANSAC
    proposes lines; the face is the line with the most inliers whose lowest contiguous run of
    inliers (gaps < MAX_GAP) holds `min_points` and starts at the floor (below FOOT_MAX_Z), so a
    heaped bucket, the machine or a slope in the roof cannot pass for the face. Least squares on
    that run, twice; then the whole face from that line (refine_face). A face outside [slope_min,
    slope_max] raises SlopeOutOfRange; no face raises TooFewPoints: never a guess. A band of more
    than MAX_FIT_POINTS points (a dense 3-D cloud) is thinned to every k-th point first."""
    in_band = np.abs(pts_pile[:, 1]) <= max_abs_y
    if in_band.sum() > MAX_FIT_POINTS:
        # a dense 3-D cloud: every k-th point of the band (RANSAC scores each of its `iterations` lines
        # on every point: 200 x 178,000 float32 is 142 MB a scan)
        pts_pile = pts_pile[in_band][:: -(-int(in_band.sum()) // MAX_FIT_POINTS)]
        in_band = np.ones(len(pts_pile), bool)
    keep = (pts_pile[:, 2] > floor_z) & (pts_pile[:, 2] < max_z) & in_band
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
    # the whole face, the points of the floor band (|z| <= floor_z) included: their model height is 0
    # before the toe, but on a rough face the face's lowest part lies in that band too, and leaving it
    # out (as RANSAC's search must, or the floor would win) cuts the face's bumps from below and
    # moves the toe
    band = (np.abs(pts_pile[:, 2]) <= floor_z) & (np.abs(pts_pile[:, 1]) <= max_abs_y)
    xa, za = np.concatenate([x, pts_pile[band, 0]]), np.concatenate([z, pts_pile[band, 2]])
    refined = refine_face(xa, za, float(sa), float(sb), threshold)
    if refined is not None and refined[2].sum() >= min_points:
        sa, sb, inl = refined
        x, z = xa, za
    alpha = math.atan(sa)
    if not slope_min <= alpha <= slope_max:
        raise SlopeOutOfRange(f"slope {math.degrees(alpha):.1f} deg outside "
                              f"[{math.degrees(slope_min):g}, {math.degrees(slope_max):g}]")
    res = float(np.sqrt(np.mean(((sa * x[inl] - z[inl] + sb) ** 2) / (1 + sa * sa))))
    return SlopeFit(alpha=alpha, toe_x=float(-sb / sa), residual=res, inliers=int(inl.sum()),
                    slope=float(sa), intercept=float(sb))


TUKEY_C = 4.685        # Tukey biweight tuning constant (95 % efficiency under Gaussian residuals)
RELIEF_START = 0.04    # m: the residual scale the whole-face fit starts from (a rough face's relief)
RELIEF_MAX = 0.05      # m: the largest residual scale it accepts (more: clutter, not relief)
CREST_STEP = 0.01      # m: the crest height h is searched on this grid
CREST_POINTS = 3000    # the crest search uses at most this many points (every k-th): it scores every point
                       # for each of up to 150 crest heights (34,000 points took 560 ms a fit, 3,000 take ~3 ms)
REFINE_ROUNDS = 8


def _tukey(u: np.ndarray) -> np.ndarray:
    return np.where(np.abs(u) < 1.0, (1.0 - u * u) ** 2, 0.0)


def refine_face(x: np.ndarray, z: np.ndarray, a: float, b: float, noise: float,
                rounds: int = REFINE_ROUNDS) -> tuple[float, float, np.ndarray] | None:
    """The face line over the whole face, from a first line z = a x + b (RANSAC's run).

    The profile (floor band included) is modelled as floor - face - crest, z = clip(a x + b, 0, h),
    and fitted robustly: each round (1) the crest height h minimises the Tukey cost of the whole
    profile over a 1 cm grid (the crest plateau, where there is one, is then not taken for face);
    (2) the points whose model height lies on the face (0 < a x + b < h) are fitted by iteratively
    reweighted least squares with Tukey's biweight at scale sigma; (3) sigma is the face's own
    robust residual scale (1.4826 MAD), between noise / 2 and RELIEF_MAX. It starts at RELIEF_START,
    wide enough that the first round sees a rough face whole rather than the short run RANSAC
    found. Returns (a, b, face inliers) or None when the face has vanished (fewer than 10 points)."""
    if len(x) < 10:
        return None
    hs = np.arange(max(float(z.min()), 0.05), float(z.max()) + CREST_STEP, CREST_STEP)
    if len(hs) == 0:
        return None         # nothing 5 cm above the floor (a bare floor with floor_z near 0): no crest to search
    sig = RELIEF_START
    floor_sig = max(noise / 2.0, 1e-3)
    stride = max(1, -(-len(x) // CREST_POINTS))       # ceil: at most CREST_POINTS in the crest search
    xs, zs = x[::stride], z[::stride].astype(np.float32)
    m = None
    for _ in range(rounds):
        pred = a * x + b
        # (1) the crest: cost of clip(pred, 0, h) for every h of the grid at once (a point whose
        # model height is below the lowest h costs the same for every h: left out of the comparison)
        ps = a * xs + b
        up = ps > hs[0]
        model = np.minimum(ps[up].astype(np.float32)[None, :], hs.astype(np.float32)[:, None])
        u = (zs[up][None, :] - model) / np.float32(TUKEY_C * sig)
        h = float(hs[int(np.argmin(np.minimum(u * u, 1.0).sum(axis=1)))])
        # (2) the face: Tukey IRLS on the points the model puts on it
        face = (pred > 0.0) & (pred < h)
        w = _tukey((z - pred) / (TUKEY_C * sig)) * face
        for _ in range(3):
            m = w > 0.0
            if m.sum() < 10:
                return None
            sw = np.sqrt(w[m])
            A = np.column_stack([x[m], np.ones(m.sum())]) * sw[:, None]
            (a, b), *_ = np.linalg.lstsq(A, z[m] * sw, rcond=None)
            a, b = float(a), float(b)
            w = _tukey((z - (a * x + b)) / (TUKEY_C * sig)) * face
        m_prev, m = m, w > 0.0
        if m.sum() < 10:
            return None
        # (3) the face's own scale
        sig_prev = sig
        sig = min(RELIEF_MAX, max(floor_sig, 1.4826 * float(np.median(np.abs(z[m] - (a * x[m] + b))))))
        if m_prev is not None and np.array_equal(m, m_prev) and abs(sig - sig_prev) < 1e-4:
            break       # converged: the same face points and scale as the round before
    if not (math.isfinite(a) and math.isfinite(b)) or a <= 0.0:
        return None
    return a, b, m


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


class SlopeFilter:
    """The pile's estimate over the last scans: a pile does not move between scans, so the fit
    published is the median (in alpha) of the latest `window` fits no older than `max_age` s, a
    whole fit (its alpha, toe and residual belong together). One scan that disagrees with it by more
    than `jump_deg` in alpha or `jump_toe` in toe x is held out; `confirm` consecutive scans that
    agree with each other and disagree with the window are a new pile, and replace the window.
    window = 1 publishes every scan's own fit (no filtering).

    Why (2026-11-28, docs/perception.md "Rough faces"): on a face with 3 cm of relief successive
    scans still differ by up to 0.3 deg at 15 deg and 3 deg at 35 deg, and the end zone moves
    0.18 m per degree on a 15 deg pile; the supervisor refuses to start an attempt whose zones
    moved by more than its zones_tolerance (2 cm) while it was armed.

    A held-out scan publishes nothing, so the stamp of what is published is always that of a scan
    which agrees with it: a new pile's first scan does not make the previous pile's slope look fresh."""

    def __init__(self, window: int = 5, max_age: float = 2.0, jump_deg: float = 3.0, jump_toe: float = 0.10,
                 confirm: int = 2):
        if window < 1 or confirm < 1 or not (max_age > 0 and jump_deg > 0 and jump_toe > 0):
            raise ValueError(f"SlopeFilter needs window >= 1, confirm >= 1 and positive max_age, jump_deg, jump_toe "
                             f"(got {window}, {confirm}, {max_age}, {jump_deg}, {jump_toe})")
        self.window, self.max_age, self.confirm = int(window), float(max_age), int(confirm)
        self.jump_alpha, self.jump_toe = math.radians(jump_deg), float(jump_toe)
        self.fits: list[tuple[float, SlopeFit]] = []       # (time, fit), oldest first
        self.pending: list[tuple[float, SlopeFit]] = []    # consecutive scans that disagree with the window
        self.held_out = 0                                   # scans held out so far

    def _agree(self, f: SlopeFit, g: SlopeFit) -> bool:
        return abs(f.alpha - g.alpha) <= self.jump_alpha and abs(f.toe_x - g.toe_x) <= self.jump_toe

    def median(self) -> SlopeFit | None:
        if not self.fits:
            return None
        order = sorted(self.fits, key=lambda tf: tf[1].alpha)
        return order[(len(order) - 1) // 2][1]

    def add(self, t: float, f: SlopeFit) -> SlopeFit | None:
        """Takes a scan's fit at time t (s, monotonic) and returns the fit to publish, or None when
        this scan is held out (nothing to publish: the last estimate keeps the stamp of the last scan
        that agreed with it)."""
        self.fits = [tf for tf in self.fits if t - tf[0] <= self.max_age]
        self.pending = [tf for tf in self.pending if t - tf[0] <= self.max_age]
        if self.window == 1:
            self.fits = [(t, f)]
            return f
        med = self.median()
        if med is None or self._agree(f, med):
            self.pending = []
            self.fits = (self.fits + [(t, f)])[-self.window:]
        elif self.pending and not self._agree(f, self.pending[-1][1]):
            self.pending = [(t, f)]          # disagrees with the window and with the scan before
            self.held_out += 1
            return None
        else:
            self.pending.append((t, f))
            if len(self.pending) < self.confirm:
                self.held_out += 1
                return None
            self.fits, self.pending = self.pending[-self.window:], []     # a new pile
        return self.median()
