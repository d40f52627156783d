"""`lhd bench perception`: ArUco detection + pose throughput on one core (cv2.setNumThreads(1)),
at 640x480 and 1280x720, on rendered frames of the marker along a drive (grayscale conversion
from bgr8 included); and the time of one slope fit on a 720-beam scan with 10 % outliers, and on a
dense 3-D cloud (160,885 points; the fit thins the band to perception/slope.MAX_FIT_POINTS)."""
from __future__ import annotations

import math
import time

import cv2
import numpy as np

from lhd_loading_ros.perception.aruco import CameraModel, MarkerDetector, image_to_gray
from lhd_loading_ros.perception.geometry import transform
from lhd_loading_ros.perception.slope import fit_slope
from lhd_loading_ros.perception.synthetic import (CAMERA_RPY, drive_poses, intrinsics, marker_texture, render,
                                                  scan_points_pile, synthetic_cloud, synthetic_scan)


def aruco_fps(width: int, height: int, n_frames: int = 30, reps: int = 4) -> float:
    rng = np.random.default_rng(0)
    K = intrinsics(width, height)
    T_pc = transform((-0.5, 0.0, 1.5), CAMERA_RPY)
    tex = marker_texture("DICT_4X4_50", 7)
    frames = []
    for T in drive_poses(np.linspace(0, 1.2, n_frames), -0.75, 0.37):
        g = render(K, width, height, np.linalg.inv(T_pc) @ T, tex, 0.12, rng)
        frames.append(np.dstack([g, g, g]).tobytes())
    det = MarkerDetector("DICT_4X4_50", 7, 0.12)
    cam = CameraModel(K, np.zeros(5))
    prev = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        best = float("inf")
        for _ in range(reps):
            t0 = time.perf_counter()
            found = 0
            for data in frames:
                gray = image_to_gray(height, width, "bgr8", width * 3, data)
                c = det.detect(gray)
                if c is not None and det.pose(c, cam) is not None:
                    found += 1
            best = min(best, time.perf_counter() - t0)
        if found < n_frames * 0.9:
            raise RuntimeError(f"benchmark frames: marker found in only {found} of {n_frames}")
    finally:
        cv2.setNumThreads(prev)
    return n_frames / best


def slope_fit_ms(reps: int = 50) -> float:
    rng = np.random.default_rng(0)
    r, amin, inc, rpy = synthetic_scan(math.radians(22.0), rng)
    pts = scan_points_pile(r, amin, inc, (0.6, 0.0, 1.6), rpy)
    t0 = time.perf_counter()
    for _ in range(reps):
        fit_slope(pts, rng)
    return (time.perf_counter() - t0) / reps * 1e3


def slope_fit_cloud_ms(reps: int = 5) -> tuple[float, int]:
    """One fit of a dense 3-D cloud (81 scan planes fanned over +-20 deg of yaw, 2,880 beams each):
    (ms, points in the cloud)."""
    rng = np.random.default_rng(0)
    pts = synthetic_cloud(math.radians(22.0), rng, yaws_deg=tuple(np.linspace(-20.0, 20.0, 81)), n=2880)
    T = transform((0.6, 0.0, 1.6), (math.pi / 2, 0.0, 0.0))
    pile = (T[:3, :3] @ pts.T).T + T[:3, 3]
    t0 = time.perf_counter()
    for _ in range(reps):
        fit_slope(pile, rng)
    return (time.perf_counter() - t0) / reps * 1e3, len(pts)


def bench_perception() -> dict:
    cloud_ms, cloud_n = slope_fit_cloud_ms()
    return {
        "aruco_fps_640x480": round(aruco_fps(640, 480), 1),
        "aruco_fps_1280x720": round(aruco_fps(1280, 720), 1),
        "slope_fit_ms": round(slope_fit_ms(), 3),
        "slope_fit_cloud_ms": round(cloud_ms, 1),
        "slope_fit_cloud_points": cloud_n,
        "threads": 1,
    }
