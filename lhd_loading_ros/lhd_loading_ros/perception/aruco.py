"""ArUco marker pose and machine forward speed, without ROS.

Pipeline: image (numpy) -> cv2.aruco.ArucoDetector -> corners of the configured marker ->
solvePnPGeneric(SOLVEPNP_IPPE_SQUARE) with the camera intrinsics -> the two marker poses of the
planar ambiguity in the camera frame -> the one consistent with the mounting and the last pose
-> pile frame through the camera extrinsic -> (planar motion) the marker's position replaced by
the camera ray through its centre (`marker_centre_ray`) met with the plane of the marker's
known height (`position_on_plane`) -> base_link through the marker-to-base offset -> v_x from a constant-velocity Kalman filter on x(t) (KalmanVelocityEstimator, the default) or
the least-squares slope of x(t) over a time window (VelocityEstimator).

Needs OpenCV >= MIN_OPENCV_VERSION: `cv2.aruco.ArucoDetector` and `DetectorParameters()`
replaced the old functional API in 4.7.0; older builds (some distribution packages) lack them.
"""
from __future__ import annotations

import math
import re
from collections import deque
from dataclasses import dataclass

import cv2
import numpy as np

from lhd_loading_ros.perception.geometry import apply, from_rt, rpy_matrix

MIN_OPENCV_VERSION = "4.7.0"
ENCODINGS = {"mono8": 1, "bgr8": 3, "rgb8": 3, "bgra8": 4, "rgba8": 4}
DISTORTION_LENGTHS = (0, 4, 5, 8, 12, 14)   # what OpenCV's camera model accepts (0: no distortion)


def _version_tuple(v: str) -> tuple[int, ...] | None:
    m = re.match(r"\s*(\d+)\.(\d+)(?:\.(\d+))?", v)
    return tuple(int(g or 0) for g in m.groups()) if m else None


def opencv_problem(version: str | None = None, module=None) -> str | None:
    """Why this OpenCV cannot run the ArUco code (None: it can). Called at node start, so an old
    distribution build ends the node with this message instead of an AttributeError or worse."""
    module = cv2 if module is None else module
    version = getattr(module, "__version__", "?") if version is None else version
    have, need = _version_tuple(str(version)), _version_tuple(MIN_OPENCV_VERSION)
    fix = "install opencv-contrib-python or opencv-python >= 4.7.0 (pip), or a newer distribution build"
    if have is None or have < need:
        return f"OpenCV {version} is too old: the ArUco pose node needs OpenCV >= {MIN_OPENCV_VERSION}; {fix}"
    aruco = getattr(module, "aruco", None)
    if aruco is None or not hasattr(aruco, "ArucoDetector"):
        return f"OpenCV {version} has no cv2.aruco.ArucoDetector (a build without the aruco module); {fix}"
    return None


class ImageEncodingError(ValueError):
    pass


class AmbiguousMarkerError(ValueError):
    """More than one marker of the machine's id in the image: which is the machine's cannot be told."""


def image_to_gray(height: int, width: int, encoding: str, step: int, data: bytes) -> np.ndarray:
    """sensor_msgs/Image fields -> uint8 grayscale array (cv_bridge is not available here)."""
    if height <= 0 or width <= 0:
        raise ImageEncodingError(f"empty image ({width}x{height}); expected a camera frame")
    if encoding not in ENCODINGS:
        raise ImageEncodingError(f"unsupported image encoding {encoding!r}; expected one of {', '.join(ENCODINGS)}")
    ch = ENCODINGS[encoding]
    if step < width * ch:
        raise ImageEncodingError(f"image step {step} bytes is shorter than a row of {width} px x {ch} channels of "
                                 f"{encoding} ({width * ch} bytes); expected step >= width x channels")
    if len(data) != step * height:
        raise ImageEncodingError(f"image data of {len(data)} bytes for {height} rows of step {step} "
                                 f"({step * height} bytes expected)")
    buf = np.frombuffer(data, dtype=np.uint8, count=step * height).reshape(height, step)[:, : width * ch]
    if ch == 1:
        return np.ascontiguousarray(buf)
    img = buf.reshape(height, width, ch)
    code = {"bgr8": cv2.COLOR_BGR2GRAY, "rgb8": cv2.COLOR_RGB2GRAY, "bgra8": cv2.COLOR_BGRA2GRAY,
            "rgba8": cv2.COLOR_RGBA2GRAY}[encoding]
    return cv2.cvtColor(img, code)


def dictionary(name: str):
    if not name.startswith("DICT_") or not hasattr(cv2.aruco, name):
        raise ValueError(f"unknown ArUco dictionary {name!r}; expected a cv2.aruco name such as DICT_4X4_50")
    return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))


@dataclass
class CameraModel:
    K: np.ndarray      # 3x3
    D: np.ndarray      # distortion coefficients
    width: int = 0     # calibrated image size (0: not given)
    height: int = 0

    @classmethod
    def from_camera_info(cls, k, d, width: int = 0, height: int = 0, distortion_model: str = "") -> "CameraModel":
        """Checked CameraInfo fields; ValueError saying what is wrong and what is expected."""
        if len(k) != 9:
            raise ValueError(f"K has {len(k)} elements; expected 9")
        K = np.array(k, dtype=float).reshape(3, 3)
        if not np.isfinite(K).all():
            raise ValueError("K has NaN or inf; expected finite intrinsics")
        if K[0, 0] <= 0 or K[1, 1] <= 0:
            raise ValueError(f"focal lengths fx={K[0, 0]:g}, fy={K[1, 1]:g}; expected > 0")
        if not np.allclose(K[2], [0.0, 0.0, 1.0]) or K[1, 0] != 0.0:
            raise ValueError(f"K's last row is {K[2].tolist()}; expected a camera matrix [[fx,s,cx],[0,fy,cy],[0,0,1]]")
        if distortion_model in ("equidistant", "fisheye"):
            raise ValueError(f"distortion model {distortion_model!r} is not supported; expected plumb_bob or "
                             "rational_polynomial (rectify fisheye images upstream)")
        if len(d) not in DISTORTION_LENGTHS:
            raise ValueError(f"{len(d)} distortion coefficients; expected one of {', '.join(map(str, DISTORTION_LENGTHS))}")
        D = np.array(d, dtype=float)
        if not np.isfinite(D).all():
            raise ValueError("distortion coefficients have NaN or inf")
        return cls(K, D if len(D) else np.zeros(5), int(width), int(height))


class MarkerDetector:
    def __init__(self, dict_name: str, marker_id: int, marker_size: float):
        if marker_size <= 0:
            raise ValueError(f"marker_size must be > 0 m, got {marker_size}")
        params = cv2.aruco.DetectorParameters()
        params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
        self.detector = cv2.aruco.ArucoDetector(dictionary(dict_name), params)
        self.marker_id = int(marker_id)
        s = marker_size / 2.0
        # IPPE_SQUARE's required object-point order: top-left, top-right, bottom-right, bottom-left
        self.obj = np.array([[-s, s, 0], [s, s, 0], [s, -s, 0], [-s, -s, 0]], dtype=np.float64)

    def detect(self, gray: np.ndarray):
        corners, ids, _ = self.detector.detectMarkers(gray)
        if ids is None:
            return None
        mine = [c for c, i in zip(corners, ids.ravel()) if int(i) == self.marker_id]
        if len(mine) > 1:
            # OpenCV's order of detections is not stable: taking the first jumped between the two markers
            # (+-19 m/s of v_x, or a spare marker's standstill, published as measured; a review, 2026-11-29)
            centres = ", ".join(f"({c.reshape(4, 2)[:, 0].mean():.0f}, {c.reshape(4, 2)[:, 1].mean():.0f})"
                                for c in mine)
            raise AmbiguousMarkerError(f"{len(mine)} markers of id {self.marker_id} in view, at pixels {centres}: "
                                       "which is the machine's is ambiguous; expected one (cover or remove the "
                                       "others, or give the machine another marker_id)")
        return mine[0].reshape(4, 2).astype(np.float64) if mine else None

    def pose(self, corners: np.ndarray, cam: CameraModel, choose=None) -> np.ndarray | None:
        """4x4 pose of the marker in the camera frame (optical: x right, y down, z forward).
        A square seen nearly face-on has two poses that fit the corners almost equally well
        (IPPE_SQUARE returns both); `choose(candidates)` picks one (default: the lower
        reprojection error, IPPE's first)."""
        n, rvecs, tvecs, _ = cv2.solvePnPGeneric(self.obj, corners, cam.K, cam.D, flags=cv2.SOLVEPNP_IPPE_SQUARE)
        cands = [from_rt(cv2.Rodrigues(r)[0], t) for r, t in zip(rvecs[:n], tvecs[:n])]
        cands = [T for T in cands if np.isfinite(T).all()]
        if not cands:
            return None
        return choose(cands) if choose is not None else cands[0]


class MountingPrior:
    """Picks among the ambiguous marker poses the one consistent with how things are mounted:
    the marker faces the camera (its normal toward the camera), the machine stands upright on
    the floor (base_link's z axis up in the pile frame) and, when both solutions are about
    equally upright (the marker right under the camera), the one nearer the last pose."""

    def __init__(self, T_pile_cam: np.ndarray, T_marker_base: np.ndarray, tie_rad: float = math.radians(2.0)):
        self.T_pile_cam = T_pile_cam
        self.R_marker_base = T_marker_base[:3, :3]
        self.tie = tie_rad
        self.last: np.ndarray | None = None     # rotation of the last chosen marker pose (pile frame)

    def __call__(self, cands: list[np.ndarray]) -> np.ndarray:
        facing = [T for T in cands if T[2, 2] < 0.0] or cands      # marker z toward the camera
        scored = []
        for T in facing:
            R_pile_base = self.T_pile_cam[:3, :3] @ T[:3, :3] @ self.R_marker_base
            tilt = math.acos(max(-1.0, min(1.0, R_pile_base[2, 2])))
            scored.append((tilt, T))
        scored.sort(key=lambda s: s[0])
        best = scored[0][1]
        if self.last is not None and len(scored) > 1 and scored[1][0] - scored[0][0] < self.tie:
            best = min((T for _, T in scored[:2]), key=lambda T: _angle(self.T_pile_cam[:3, :3] @ T[:3, :3], self.last))
        self.last = self.T_pile_cam[:3, :3] @ best[:3, :3]
        return best

    def reset(self) -> None:
        self.last = None


def _angle(Ra: np.ndarray, Rb: np.ndarray) -> float:
    c = (np.trace(Ra.T @ Rb) - 1.0) / 2.0
    return math.acos(max(-1.0, min(1.0, c)))


class VelocityEstimator:
    """v_x as the least-squares slope of x(t) over the last `window` seconds (at least
    `min_samples` poses): a finite difference filtered over the window."""

    def __init__(self, window: float, min_samples: int = 3):
        if window <= 0:
            raise ValueError(f"velocity window must be > 0 s, got {window}")
        self.window = window
        self.min_samples = min_samples
        self.samples: deque = deque()

    def add(self, t: float, x: float) -> bool:
        """Add a measurement; False when its stamp is not after the last one (a repeated
        frame adds nothing; a backward jump -- bag loop, sim reset -- restarts the window)."""
        if self.samples and t <= self.samples[-1][0]:
            if t == self.samples[-1][0]:
                return False
            self.samples.clear()
            self.samples.append((t, x))
            return False
        self.samples.append((t, x))
        while self.samples and t - self.samples[0][0] > self.window:
            self.samples.popleft()
        return True

    def reset(self) -> None:
        self.samples.clear()

    @property
    def last_t(self) -> float | None:
        return self.samples[-1][0] if self.samples else None

    def velocity(self) -> float | None:
        if len(self.samples) < self.min_samples:
            return None
        ts = np.array([s[0] for s in self.samples])
        xs = np.array([s[1] for s in self.samples])
        ts = ts - ts.mean()
        den = float(np.dot(ts, ts))
        if den <= 0:
            return None
        return float(np.dot(ts, xs - xs.mean()) / den)


class KalmanVelocityEstimator:
    """v_x from x(t) with a constant-velocity Kalman filter: state [x, v], the speed a random
    walk driven by white acceleration of spectral density `accel_noise` (m^2/s^3), x measured
    with white noise of `position_noise` (m, standard deviation). The speed it reports belongs
    to the last measurement's instant: no half-window lag as the least-squares slope has (0.13 s
    with a 0.3 s window; docs/perception.md compares both on simulated attempts).

    Same interface as VelocityEstimator: add() refuses a repeated stamp and restarts on a
    backward one; a gap longer than `max_gap` restarts too (the speed from before a long gap
    is not this one). It starts with the speed unknown (a diffuse prior) and reports a speed
    from the `min_samples`-th measurement on (3: as the window estimator, a speed always rests
    on three consecutive detections)."""

    V0_SD = 2.0     # m/s: the speed's prior standard deviation (a few times the machine's top speed)

    def __init__(self, accel_noise: float = 1.0, position_noise: float = 0.001, max_gap: float = 0.5,
                 min_samples: int = 3):
        for name, v in (("accel_noise", accel_noise), ("position_noise", position_noise), ("max_gap", max_gap)):
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"Kalman velocity filter: {name} must be a finite number > 0, got {v}")
        self.q, self.r, self.max_gap = float(accel_noise), float(position_noise) ** 2, float(max_gap)
        self.min_samples = max(2, int(min_samples))
        self.reset()

    def reset(self) -> None:
        self.x: np.ndarray | None = None     # [x, v]
        self.P: np.ndarray | None = None
        self.last_t: float | None = None
        self.n = 0                            # measurements since the start

    def add(self, t: float, x: float) -> bool:
        if self.last_t is not None and t <= self.last_t:
            if t == self.last_t:
                return False
            self.reset()
            self._start(t, x)
            return False
        if self.last_t is not None and t - self.last_t > self.max_gap:
            self.reset()
        if self.x is None:
            self._start(t, x)
            return True
        self._correct(t, x)
        return True

    def _correct(self, t: float, x: float) -> None:
        """A measurement after the last one (the stamp checks are done): predict, correct."""
        dt = t - self.last_t
        F = np.array([[1.0, dt], [0.0, 1.0]])
        Q = self.q * np.array([[dt ** 3 / 3.0, dt ** 2 / 2.0], [dt ** 2 / 2.0, dt]])
        xp = F @ self.x
        P = F @ self.P @ F.T + Q
        s = P[0, 0] + self.r
        k = P[:, 0] / s
        self.x = xp + k * (x - xp[0])
        self.P = P - np.outer(k, P[0])
        self.P = 0.5 * (self.P + self.P.T)
        self.last_t = t
        self.n += 1

    def _start(self, t: float, x: float) -> None:
        """The first measurement: x known to the measurement noise, the speed unknown (a
        diffuse prior, V0_SD); the next measurements then give the least-squares line."""
        self.x = np.array([x, 0.0])
        self.P = np.diag([self.r, self.V0_SD ** 2])
        self.last_t, self.n = t, 1

    def velocity(self) -> float | None:
        return None if self.x is None or self.n < self.min_samples else float(self.x[1])

    def speed_sd(self) -> float | None:
        """Standard deviation of the speed estimate (m/s) the filter believes."""
        return None if self.P is None else float(math.sqrt(max(self.P[1, 1], 0.0)))


class InertialVelocityEstimator(KalmanVelocityEstimator):
    """v_x from the camera's x(t) and an accelerometer's acceleration along x, a(t): a Kalman
    filter on [x, v, b] (b: the accelerometer's bias along x) that integrates the measured
    acceleration between two images and corrects with each image's x. A constant-velocity filter
    must infer a speed change from 30 positions a second and lags an abrupt one (the bucket
    meeting the pile: 0.3 m/s lost in 0.1 s); an accelerometer measures it as it happens.

    Acceleration samples (`add_accel(t, a)`, a in m/s^2, gravity already removed and turned into
    the x direction of the position) are each the mean over the interval since the previous one,
    as an IMU's filtered output is: sample i holds over (max(t_{i-1}, t_i - span), t_i], span =
    accel_timeout or, once the stream's period is known, 1.5 periods (a sample after lost ones
    stands for its own period, not the gap's), and the newest one is held for `hold` past its stamp (one period of a 50 Hz IMU by default,
    20 ms: longer holds spread a contact's one-sample spike). An interval no sample
    covers (an IMU that stopped, a gap in its stream) falls back to the constant-velocity model
    of KalmanVelocityEstimator with `accel_noise`; with no acceleration at all the [x, v] part is
    exactly that filter (the bias is then neither used nor changed).

    Noises: `imu_accel_noise`, the spectral density (m^2/s^3) of the error of the integrated
    acceleration (the sensor's white noise, about sigma^2 / rate, plus what the model leaves out:
    the lever arm between the IMU and the tracked point, vibration); `bias_walk` (m^2/s^5), the
    bias's random walk; the bias's prior sd BIAS0_SD covers a few degrees of mounting error
    (g sin 3 deg = 0.5 m/s^2). The bias estimate survives a reset (a lost marker does not change
    the sensor), with its variance grown back to the prior's.

    Samples that arrive after an image they should have served (the image was processed first:
    the IMU's next sample is up to 20 ms after the image's instant and the two travel separately)
    are not lost: the filter keeps its states of the last HISTORY_S seconds and, at the next image,
    runs again from the last state before the late sample's interval with every sample now known.
    Only the image nearest the newest samples is served by a held sample, and a node can avoid even
    that by holding the image back until the covering sample has come (`awaits_sample`; the ArUco
    node's imu_accel_wait).

    A KalmanVelocityEstimator (its add(): the same stamp checks, its velocity() and speed_sd())
    with the accelerometer in the prediction."""

    BIAS0_SD = 0.5          # m/s^2
    MAX_SAMPLES = 512       # accelerometer samples kept (10 s at 50 Hz)
    HISTORY_S = 0.5         # s of filter states kept for late samples
    JUMP_M = 0.10           # m: a larger innovation is a displacement; the filter starts again there

    def __init__(self, accel_noise: float = 1.0, position_noise: float = 0.001, max_gap: float = 0.5,
                 imu_accel_noise: float = 0.01, bias_walk: float = 1e-3, accel_timeout: float = 0.1,
                 min_samples: int = 3, hold: float = 0.02):
        for name, v in (("accel_noise", accel_noise), ("position_noise", position_noise), ("max_gap", max_gap),
                        ("imu_accel_noise", imu_accel_noise), ("bias_walk", bias_walk),
                        ("accel_timeout", accel_timeout)):
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"inertial velocity filter: {name} must be a finite number > 0, got {v}")
        self.q, self.r, self.max_gap = float(accel_noise), float(position_noise) ** 2, float(max_gap)
        self.qa, self.qb, self.accel_timeout = float(imu_accel_noise), float(bias_walk), float(accel_timeout)
        self.min_samples = max(2, int(min_samples))
        self.hold = float(hold)
        self.accel: deque = deque(maxlen=self.MAX_SAMPLES)      # (t, a)
        self._intervals: deque = deque(maxlen=16)               # the last intervals between samples (s)
        self.bias, self.bias_var = 0.0, self.BIAS0_SD ** 2
        self.inertial_s = self.blind_s = 0.0    # time integrated with / without the accelerometer
        self.jumps = 0                          # displacements the filter started again after
        self.reset()

    def reset(self) -> None:
        if getattr(self, "x", None) is not None:
            self.bias = float(self.x[2])
        self.x: np.ndarray | None = None      # [x, v, b]
        self.P: np.ndarray | None = None
        self.last_t: float | None = None
        self.n = 0
        self.hist: deque = deque()            # (t, x measured, state, covariance, n) after each image
        self._dirty_from: float | None = None  # a late sample covers time after this: run again from it
        self.reruns = 0

    def add_accel(self, t: float, a: float) -> bool:
        """One accelerometer sample; False (not kept) for a non-finite value or a repeated stamp.
        A stamp that goes back clears the older samples (a bag loop, a restart: another time line)."""
        if not (math.isfinite(t) and math.isfinite(a)):
            return False
        if self.accel and t <= self.accel[-1][0]:
            if t == self.accel[-1][0]:
                return False
            self.accel.clear()
            self._intervals.clear()
        span = self._span()
        start = max(t - span, self.accel[-1][0]) if self.accel else t - span
        self.accel.append((float(t), float(a)))
        if len(self.accel) >= 2:
            self._intervals.append(self.accel[-1][0] - self.accel[-2][0])
        if self.last_t is not None and start < self.last_t:     # an image already used this interval
            self._dirty_from = start if self._dirty_from is None else min(self._dirty_from, start)
        return True

    def awaits_sample(self, t: float, live: float) -> bool:
        """True when an image at t should wait for the accelerometer: the stream is live (its
        newest sample is at most `live` seconds before t) but has not covered t yet. The sample
        that covers t comes up to one IMU period after it; the hold only predicts that interval."""
        if not self.accel:
            return False
        last = self.accel[-1][0]
        return last < t <= last + live

    def _span(self) -> float:
        """How far back from its stamp a sample may cover: accel_timeout, or, once the stream's
        period is known (the median of its last intervals), 1.5 periods when that is shorter. A
        sample after a gap (samples lost on the way, a node too busy to take them) then stands for
        its own period, not for the whole gap: the gap runs as the constant-velocity filter."""
        if len(self._intervals) >= 4:
            return min(self.accel_timeout, 1.5 * float(np.median(self._intervals)))
        return self.accel_timeout

    def _segments(self, t0: float, t1: float):
        """(dt, a or None) pieces of (t0, t1]: a where a sample covers the piece, None where none does."""
        out, edge = [], t0
        prev_t = None
        span = self._span()
        for ts, a in self.accel:
            if ts <= t0:
                prev_t = ts
                continue
            start = max(ts - span, prev_t if prev_t is not None else -math.inf)
            if start > edge:                       # a gap before this sample's interval
                out.append((min(start, t1) - edge, None))
                edge = min(start, t1)
            end = min(ts, t1)
            if end > edge:
                out.append((end - edge, a))
                edge = end
            prev_t = ts
            if edge >= t1:
                return out
        if self.accel and edge < t1 and self.hold > 0.0:      # the newest sample, held for `hold`
            ts, a = self.accel[-1]
            end = min(t1, ts + min(self.hold, self.accel_timeout))
            if ts <= edge < end:
                out.append((end - edge, a))
                edge = end
        if edge < t1:
            out.append((t1 - edge, None))
        return out

    def _predict(self, dt: float, a: float | None) -> None:
        if dt <= 0.0:
            return
        if a is None:           # no accelerometer here: the constant-velocity model, the bias untouched
            F = np.array([[1.0, dt, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
            Q = np.zeros((3, 3))
            Q[:2, :2] = self.q * np.array([[dt ** 3 / 3.0, dt ** 2 / 2.0], [dt ** 2 / 2.0, dt]])
            self.x = F @ self.x
            self.blind_s += dt
        else:
            F = np.array([[1.0, dt, -0.5 * dt * dt], [0.0, 1.0, -dt], [0.0, 0.0, 1.0]])
            Q = np.zeros((3, 3))
            Q[:2, :2] = self.qa * np.array([[dt ** 3 / 3.0, dt ** 2 / 2.0], [dt ** 2 / 2.0, dt]])
            Q[2, 2] = self.qb * dt
            self.x = F @ self.x + np.array([0.5 * dt * dt * a, dt * a, 0.0])
            self.inertial_s += dt
        self.P = F @ self.P @ F.T + Q

    def _correct(self, t: float, x: float) -> None:
        if self._dirty_from is not None:
            self._rerun(self._dirty_from)
        self._step(t, x)
        self._remember(t, x)
        while self.hist and self.hist[0][0] < t - self.HISTORY_S and len(self.hist) > 1:
            self.hist.popleft()
        keep_from = self.hist[0][0] - self.accel_timeout
        while self.accel and self.accel[0][0] < keep_from and len(self.accel) > 1:
            self.accel.popleft()

    def _step(self, t: float, x: float) -> None:
        """Predict from last_t to t with the samples known now, correct with x. An innovation over
        JUMP_M is a displacement, not motion (the machine placed by hand, a twin that puts it back
        for the next attempt; at 0.5 m/s a frame moves 2 cm): the filter starts again at x, with the
        bias it had, instead of reading the jump as acceleration and learning it as bias."""
        for dt, a in self._segments(self.last_t, t):
            self._predict(dt, a)
        if abs(x - self.x[0]) > self.JUMP_M:
            self.jumps += 1
            bias, bias_var = float(self.x[2]), float(self.P[2, 2])
            self.x = np.array([x, 0.0, bias])
            self.P = np.diag([self.r, self.V0_SD ** 2, bias_var])
            self.last_t, self.n = t, 1
            return
        s = self.P[0, 0] + self.r
        k = self.P[:, 0] / s
        self.x = self.x + k * (x - self.x[0])
        self.P = self.P - np.outer(k, self.P[0])
        self.P = 0.5 * (self.P + self.P.T)
        self.bias_var = float(self.P[2, 2])
        self.last_t = t
        self.n += 1

    def _remember(self, t: float, x: float) -> None:
        self.hist.append((t, x, self.x.copy(), self.P.copy(), self.n))

    def _rerun(self, t_from: float) -> None:
        """Late samples cover time after t_from: go back to the last kept state at or before it
        and filter the images since then again with every sample known now."""
        self._dirty_from = None
        hist = list(self.hist)
        k = max((i for i, h in enumerate(hist) if h[0] <= t_from), default=0)
        t0, _, X, P, n = hist[k]
        self.x, self.P, self.last_t, self.n = X.copy(), P.copy(), t0, n
        ins, blind = self.inertial_s, self.blind_s      # the time counters count each interval once
        self.hist = deque(hist[:k + 1])
        for t, x, _, _, _ in hist[k + 1:]:
            self._step(t, x)
            self._remember(t, x)
        self.inertial_s, self.blind_s = ins, blind
        self.reruns += 1

    def _start(self, t: float, x: float) -> None:
        self.x = np.array([x, 0.0, self.bias])
        self.P = np.diag([self.r, self.V0_SD ** 2, max(self.bias_var, self.BIAS0_SD ** 2)])
        self.last_t, self.n = t, 1
        self.hist.clear()
        self._dirty_from = None
        self._remember(t, x)

    def bias_estimate(self) -> float:
        return float(self.x[2]) if self.x is not None else self.bias


def level(T: np.ndarray) -> np.ndarray:
    """Keep the position and the heading (yaw) of a pose, drop roll and pitch. For a machine
    on a flat floor: a small marker seen nearly face-on has a few degrees of tilt ambiguity,
    which a lever arm to base_link would turn into centimetres."""
    yaw = math.atan2(T[1, 0], T[0, 0])
    out = np.eye(4)
    out[:3, :3] = [[math.cos(yaw), -math.sin(yaw), 0.0], [math.sin(yaw), math.cos(yaw), 0.0], [0.0, 0.0, 1.0]]
    out[:3, 3] = T[:3, 3]
    return out


def diagonal_crossing(corners: np.ndarray) -> np.ndarray:
    """Where the diagonals (corner 0 - corner 2, corner 1 - corner 3) of a quadrilateral cross.
    A perspective image keeps a square's centre on both diagonals, so in an UNDISTORTED image
    (or in normalised camera coordinates) this is the image of the centre; the mean of the
    corners is off it when the square is seen obliquely. ValueError when the four points do not
    form a quadrilateral whose diagonals cross inside it (degenerate or self-crossing)."""
    c = np.asarray(corners, dtype=float).reshape(4, 2)
    h = np.c_[c, np.ones(4)]
    p = np.cross(np.cross(h[0], h[2]), np.cross(h[1], h[3]))
    if not np.isfinite(p).all() or abs(p[2]) <= 1e-12 * max(1.0, float(np.abs(p[:2]).max())):
        raise ValueError("marker corners are degenerate: the diagonals do not cross")
    x = p[:2] / p[2]
    # inside both diagonals (a proper convex quadrilateral), with a small tolerance
    for a, b in ((c[0], c[2]), (c[1], c[3])):
        d = b - a
        t = float(np.dot(x - a, d) / max(np.dot(d, d), 1e-300))
        if not (-1e-9 <= t <= 1.0 + 1e-9):
            raise ValueError("marker corners are degenerate: the diagonals cross outside the marker")
    return x


def marker_centre_ray(corners: np.ndarray, cam: CameraModel) -> np.ndarray:
    """Normalised camera coordinates (x/z, y/z) of the ray through the marker's centre: the
    detected pixel corners undistorted first (cv2.undistortPoints with the camera's K and D), and
    their diagonals crossed there. (Crossing them in the distorted image and undistorting the
    crossing would be off by the lens's bending of the diagonals: 0.1-0.4 px, 0.2-1 mm here.)"""
    n = cv2.undistortPoints(np.asarray(corners, dtype=np.float64).reshape(4, 1, 2), cam.K, cam.D).reshape(4, 2)
    return diagonal_crossing(n)


def position_on_plane(ray_xy: np.ndarray, T_pile_cam: np.ndarray, height: float) -> np.ndarray | None:
    """Where the camera ray with normalised coordinates `ray_xy` (marker_centre_ray) meets the
    horizontal plane z = `height` of the pile frame (the marker's height on a machine standing
    on the floor).

    Why: the marker's position from solvePnP carries its distance error along the line of
    sight, and a 0.12 m marker seen from 1.65 m has a few millimetres of it (a 1 % scale error
    of the marker's apparent size moves x by 1 % of its offset from the camera axis); the
    direction of the ray through its centre is known to a fraction of a pixel. With the
    height known, that direction alone fixes the position (docs/perception.md: x error sd 3.6 ->
    0.26 mm on the twin's images). None when the ray does not reach the plane (parallel to it,
    or the plane behind the camera)."""
    ray = T_pile_cam[:3, :3] @ np.array([float(ray_xy[0]), float(ray_xy[1]), 1.0])
    o = T_pile_cam[:3, 3]
    if abs(ray[2]) < 1e-9:
        return None
    s = (float(height) - o[2]) / ray[2]
    if not (s > 0.0 and math.isfinite(s)):
        return None
    return o + s * ray


def project(K: np.ndarray, T_cam_obj: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Pinhole projection of object points (n, 3) given the object's pose in the camera."""
    pc = apply(T_cam_obj, pts)
    uv = pc[:, :2] / pc[:, 2:3]
    return uv @ K[:2, :2].T + K[:2, 2]


QUATERNION_NORM_TOLERANCE = 0.01   # |q| of an IMU's orientation: 1 within this
# m/s^2: the largest specific force an accelerometer on the rear frame is taken to report. The
# machine drives below 1 m/s and stops within about 0.2 s (5 m/s^2); with gravity and the shocks
# of the bucket entering the pile, 4 g is well above anything its frame does. A sample beyond it
# is a fault (a spike of 1000 m/s^2 restarted the speed filter at every image, silently: a review)
MAX_SPECIFIC_FORCE = 39.2


def roll_pitch(qx: float, qy: float, qz: float, qw: float) -> tuple[float, float]:
    """Roll and pitch (rad, REP 103: R = Rz(yaw) Ry(pitch) Rx(roll), positive pitch = nose down) of a
    unit quaternion, e.g. an IMU's orientation; ValueError for a non-finite or zero quaternion."""
    q = np.array([qx, qy, qz, qw], dtype=float)
    n = float(np.linalg.norm(q))
    if not (np.isfinite(q).all() and n > 1e-9):
        raise ValueError(f"orientation quaternion {q.tolist()} is not a rotation; expected a finite, non-zero (x, y, z, w)")
    if abs(n - 1.0) > QUATERNION_NORM_TOLERANCE:
        # a driver's quaternion is normalised to float precision; one of norm 0.5 is a corrupt
        # message, and normalising it read (0, 0.1, 0, 0.49) as a 23 deg pitch (a review's fault
        # injection, 2026-11-28)
        raise ValueError(f"orientation quaternion {q.tolist()} has norm {n:.4g}; expected a unit quaternion "
                         f"(norm 1 +- {QUATERNION_NORM_TOLERANCE:g})")
    x, y, z, w = q / n
    r20 = 2.0 * (x * z - w * y)
    r21 = 2.0 * (y * z + w * x)
    r22 = 1.0 - 2.0 * (x * x + y * y)
    return math.atan2(r21, r22), math.asin(max(-1.0, min(1.0, -r20)))


def forward_acceleration(f_body, roll: float, pitch: float, yaw: float) -> float:
    """The acceleration along the pile frame's x (m/s^2) of an accelerometer whose specific force
    is f_body (m/s^2, its own axes; sensor_msgs/Imu linear_acceleration: gravity included, +9.81
    on z at rest) and whose orientation is roll, pitch, yaw (REP 103). The world acceleration is
    R f + g with g = (0, 0, -9.81): gravity has no x component, so it is row x of R times f.
    A pitch error e leaks g sin(e) into it (0.17 m/s^2 per degree): the velocity filter's bias
    state takes up a constant one."""
    f = np.asarray(f_body, dtype=float).reshape(3)
    if not np.isfinite(f).all():
        raise ValueError(f"linear acceleration {f.tolist()} is not finite")
    if float(np.linalg.norm(f)) > MAX_SPECIFIC_FORCE:
        raise ValueError(f"linear acceleration {np.round(f, 2).tolist()} m/s^2 (|f| = {np.linalg.norm(f):.1f}) is beyond "
                         f"the {MAX_SPECIFIC_FORCE:g} m/s^2 (4 g) the machine's rear frame can feel; expected "
                         "m/s^2 with gravity included (a spike, or a smaller unit such as mg or cm/s^2?)")
    return float(rpy_matrix(roll, pitch, yaw)[0] @ f)


class GravityCheck:
    """Does an IMU's linear_acceleration carry gravity in m/s^2, as REP 145 asks? A machine on the
    ground cannot accelerate vertically for long, so over a second the mean specific force is
    gravity plus at most the drive's horizontal acceleration: |mean f| about 9.81 (9.81 to 10.7 for
    braking at 5 m/s^2). An IMU that reports in g reads about 1, one with gravity removed about 0;
    each passes the per-sample 4 g bound (forward_acceleration), and in g the filter would take a
    tenth of every acceleration (noticed 2026-11-28). The mean is over the samples of the last
    `window` s, judged once they span `min_span` s with `min_samples` of them; until then, and
    while |mean f| lies outside [low, high], `problem()` says why (the accelerations are then not
    used; the tilt is, it comes from the orientation)."""

    def __init__(self, window: float = 1.0, min_span: float = 0.5, min_samples: int = 10,
                 low: float = 0.5 * 9.81, high: float = 1.5 * 9.81):
        self.window, self.min_span, self.min_samples = window, min_span, min_samples
        self.low, self.high = low, high
        self.samples: deque = deque()      # (t, fx, fy, fz)
        self.mean_norm: float | None = None

    def add(self, t: float, f) -> None:
        if self.samples and t < self.samples[-1][0]:
            self.samples.clear()            # another time line (a bag loop, a restart)
        self.samples.append((t, float(f[0]), float(f[1]), float(f[2])))
        while self.samples and self.samples[0][0] <= t - self.window:
            self.samples.popleft()
        if len(self.samples) >= self.min_samples and t - self.samples[0][0] >= self.min_span:
            m = np.mean(np.asarray(self.samples)[:, 1:], axis=0)
            self.mean_norm = float(np.linalg.norm(m))

    def problem(self) -> str | None:
        if self.mean_norm is None:
            return "not judged yet (fewer than {} samples over {:g} s)".format(self.min_samples, self.min_span)
        if self.low <= self.mean_norm <= self.high:
            return None
        return (f"the IMU's specific force averages {self.mean_norm:.2f} m/s^2 over the last {self.window:g} s, but a "
                f"machine on the ground feels gravity, 9.81 (REP 145: linear_acceleration in m/s^2, gravity included; "
                f"accepted {self.low:.1f}-{self.high:.1f}): an IMU reporting in g, or with gravity removed?")


def tilted_base_position(ray_xy: np.ndarray, T_pile_cam: np.ndarray, yaw: float, roll: float, pitch: float,
                         marker_in_base: np.ndarray, pivot_front_x: float, contact_z: float) -> np.ndarray | None:
    """base_link's position (pile frame) from the camera ray through the marker's centre when the
    machine is tilted by `roll` and `pitch` (an IMU on the rear frame) and heads `yaw` (the marker).

    A machine on a flat floor tilts about the wheels that stay on it: nose down (pitch > 0: the
    rear lifts when the boom pries at a buried bucket) about the front axle's floor contact at
    (pivot_front_x, 0, contact_z) in base_link, nose up about the rear axle's, (0, 0, contact_z)
    (base_link is the rear axle's centre; contact_z = -wheel radius). With that contact on the
    floor (z = 0) the tilt fixes base_link's height, hence the marker's (`marker_in_base`: the
    marker's centre in base_link), and the ray meets the marker's horizontal plane there.
    Levelled (position_on_plane at the upright height), a marker 0.21 m above base_link on a
    machine tilted 10 deg about a front axle 0.8 m ahead is placed 6 cm short and its lever arm
    moves it 4 cm more: the speed of that tilting is what the camera alone mistakes for driving.
    None when the ray misses the plane."""
    R = rpy_matrix(roll, pitch, yaw)
    contact = np.array([pivot_front_x if pitch >= 0.0 else 0.0, 0.0, contact_z])
    z_base = -float((R @ contact)[2])
    m = R @ np.asarray(marker_in_base, dtype=float)
    p_marker = position_on_plane(ray_xy, T_pile_cam, z_base + float(m[2]))
    if p_marker is None:
        return None
    return p_marker - m
