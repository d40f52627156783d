"""ArUco marker pose and machine forward speed, without ROS.

Pipeline: image (numpy) -> cv2.aruco.ArucoDetector -> corners of the configured marker ->
solvePnP(SOLVEPNP_IPPE_SQUARE) with the camera intrinsics -> marker pose in the camera frame
-> pile frame through the camera extrinsic -> base_link through the marker-to-base offset ->
v_x from a least-squares slope of x(t) over a time window (a filtered finite difference).
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import math

import cv2
import numpy as np

from lhd_loading_ros.perception.geometry import apply, from_rt

ENCODINGS = {"mono8": 1, "bgr8": 3, "rgb8": 3, "bgra8": 4, "rgba8": 4}


class ImageEncodingError(ValueError):
    pass


def image_to_gray(height: int, width: int, encoding: str, step: int, data: bytes) -> np.ndarray:
    """sensor_msgs/Image fields -> uint8 grayscale array (cv_bridge is not available here)."""
    if encoding not in ENCODINGS:
        raise ImageEncodingError(f"unsupported image encoding {encoding!r}; expected one of {', '.join(ENCODINGS)}")
    ch = ENCODINGS[encoding]
    if step < width * ch or len(data) < step * height:
        raise ImageEncodingError(f"image buffer too small: {len(data)} bytes for {height} rows of step {step} "
                                 f"({width} px x {ch} channels of {encoding})")
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

    @classmethod
    def from_camera_info(cls, k, d) -> "CameraModel":
        K = np.array(k, dtype=float).reshape(3, 3)
        if K[0, 0] <= 0 or K[1, 1] <= 0:
            raise ValueError("CameraInfo has no valid intrinsics (K[0,0] and K[1,1] must be > 0)")
        return cls(K, np.array(d, dtype=float) if len(d) else np.zeros(5))


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
        for c, i in zip(corners, ids.ravel()):
            if int(i) == self.marker_id:
                return c.reshape(4, 2).astype(np.float64)
        return None

    def pose(self, corners: np.ndarray, cam: CameraModel) -> np.ndarray | None:
        """4x4 pose of the marker in the camera frame (optical: x right, y down, z forward)."""
        ok, rvec, tvec = cv2.solvePnP(self.obj, corners, cam.K, cam.D, flags=cv2.SOLVEPNP_IPPE_SQUARE)
        if not ok:
            return None
        R, _ = cv2.Rodrigues(rvec)
        return from_rt(R, tvec)


class VelocityEstimator:
    """v_x as the least-squares slope of x(t) over the last `window` seconds (at least
    `min_samples` poses): a finite difference filtered over the window."""

    def __init__(self, window: float, min_samples: int = 3):
        if window <= 0:
            raise ValueError(f"velocity window must be > 0 s, got {window}")
        self.window = window
        self.min_samples = min_samples
        self.samples: deque = deque()

    def add(self, t: float, x: float) -> None:
        if self.samples and t <= self.samples[-1][0]:
            self.samples.clear()  # time went backwards (bag loop, sim reset): start over
        self.samples.append((t, x))
        while self.samples and t - self.samples[0][0] > self.window:
            self.samples.popleft()

    def reset(self) -> None:
        self.samples.clear()

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


def level(T: np.ndarray) -> np.ndarray:
    """Keep the position and the heading (yaw) of a pose, drop roll and pitch. For a machine
    on a flat floor: a small marker seen nearly face-on has a few degrees of tilt ambiguity,
    which a lever arm to base_link would turn into centimetres."""
    yaw = math.atan2(T[1, 0], T[0, 0])
    out = np.eye(4)
    out[:3, :3] = [[math.cos(yaw), -math.sin(yaw), 0.0], [math.sin(yaw), math.cos(yaw), 0.0], [0.0, 0.0, 1.0]]
    out[:3, 3] = T[:3, 3]
    return out


def project(K: np.ndarray, T_cam_obj: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Pinhole projection of object points (n, 3) given the object's pose in the camera."""
    pc = apply(T_cam_obj, pts)
    uv = pc[:, :2] / pc[:, 2:3]
    return uv @ K[:2, :2].T + K[:2, 2]
