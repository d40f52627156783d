"""Perception on realistic synthetic data: a real ArUco marker warped into a pinhole camera
along a straight 0.37 m/s drive (noise, blur, occlusion), LiDAR scans of 15-30 deg piles with
1 cm noise, 10 % outliers, floor and back wall."""
import math
import re

import numpy as np
import pytest

from lhd_loading_ros.perception.aruco import (CameraModel, ImageEncodingError, KalmanVelocityEstimator,
                                              MarkerDetector, VelocityEstimator, image_to_gray, level)
from lhd_loading_ros.perception.geometry import apply, quaternion_xyzw, rpy_matrix, transform
from lhd_loading_ros.perception.slope import TooFewPoints, fit_slope, scan_problem, scan_to_points
from lhd_loading_ros.perception.synthetic import (CAMERA_RPY, drive_poses, intrinsics, marker_texture, render,
                                                  scan_points_pile, synthetic_scan)

CAM_XYZ = (-0.5, 0.0, 1.5)
SIZE = 0.12


def drive_sequence(rng, n=45, fps=30.0, speed=0.37, occlusion_every=0, width=640, height=480):
    K = intrinsics(width, height)
    T_pile_cam = transform(CAM_XYZ, CAMERA_RPY)
    tex = marker_texture("DICT_4X4_50", 7)
    t = np.arange(n) / fps
    truth = drive_poses(t, -0.75, speed)
    frames = []
    for k, T_pm in enumerate(truth):
        occ = 0.3 if occlusion_every and k % occlusion_every == 0 else 0.0
        img = render(K, width, height, np.linalg.inv(T_pile_cam) @ T_pm, tex, SIZE, rng, noise=4.0, blur=3,
                     occlusion=occ)
        frames.append(img)
    return K, T_pile_cam, t, truth, frames


def test_marker_pose_error_below_1_cm_along_the_drive():
    rng = np.random.default_rng(0)
    K, T_pile_cam, t, truth, frames = drive_sequence(rng)
    det = MarkerDetector("DICT_4X4_50", 7, SIZE)
    cam = CameraModel(K, np.zeros(5))
    T_mb = transform((0.10, 0.0, -0.213), (0, 0, 0))
    errs, base_errs = [], []
    for img, T_pm in zip(frames, truth):
        c = det.detect(img)
        assert c is not None
        est = T_pile_cam @ det.pose(c, cam)
        errs.append(np.linalg.norm(est[:3, 3] - T_pm[:3, 3]))
        yaw_err = math.atan2(est[1, 0], est[0, 0]) - math.atan2(T_pm[1, 0], T_pm[0, 0])
        assert abs(math.degrees(yaw_err)) < 2.0
        # base_link through the offset: levelled (planar_motion), the tilt ambiguity of a small
        # face-on marker does not reach it through the lever arm
        base = level(est) @ T_mb
        base_errs.append(np.linalg.norm(base[:3, 3] - (T_pm @ T_mb)[:3, 3]))
    assert max(errs) < 0.01, max(errs)
    assert max(base_errs) < 0.01, max(base_errs)


def test_speed_error_below_0_02_m_s_when_visible():
    rng = np.random.default_rng(1)
    K, T_pile_cam, t, truth, frames = drive_sequence(rng)
    det = MarkerDetector("DICT_4X4_50", 7, SIZE)
    cam = CameraModel(K, np.zeros(5))
    vel = VelocityEstimator(0.3)
    speeds = []
    for ti, img in zip(t, frames):
        T = T_pile_cam @ det.pose(det.detect(img), cam)  # the marker's position, as the node does
        vel.add(ti, T[0, 3])
        v = vel.velocity()
        if v is not None:
            speeds.append(v)
    assert len(speeds) > 30
    assert max(abs(v - 0.37) for v in speeds) < 0.02


def test_partial_occlusion_loses_the_marker_without_false_detections():
    rng = np.random.default_rng(2)
    K, T_pile_cam, t, truth, frames = drive_sequence(rng, n=12, occlusion_every=3)
    det = MarkerDetector("DICT_4X4_50", 7, SIZE)
    seen = [det.detect(f) is not None for f in frames]
    assert not seen[0] and not seen[3] and all(seen[k] for k in (1, 2, 4, 5))
    # another id in the dictionary is not our marker
    assert MarkerDetector("DICT_4X4_50", 8, SIZE).detect(frames[1]) is None


def test_image_conversion_encodings():
    gray = (np.arange(12 * 10) % 256).astype(np.uint8).reshape(10, 12)
    assert np.array_equal(image_to_gray(10, 12, "mono8", 12, gray.tobytes()), gray)
    padded = np.zeros((10, 16), np.uint8)
    padded[:, :12] = gray
    assert np.array_equal(image_to_gray(10, 12, "mono8", 16, padded.tobytes()), gray)
    bgr = np.dstack([gray, gray, gray])
    assert np.abs(image_to_gray(10, 12, "bgr8", 36, bgr.tobytes()).astype(int) - gray).max() <= 1
    rgb = np.zeros((10, 12, 3), np.uint8)
    rgb[..., 0] = 255  # pure red
    assert image_to_gray(10, 12, "rgb8", 36, rgb.tobytes())[0, 0] == 76  # 0.299 * 255
    assert image_to_gray(10, 12, "bgr8", 36, rgb.tobytes())[0, 0] == 29  # read as blue: 0.114 * 255
    with pytest.raises(ImageEncodingError, match="unsupported image encoding '16UC1'; expected one of mono8"):
        image_to_gray(10, 12, "16UC1", 24, bytes(240))
    with pytest.raises(ImageEncodingError, match=r"image data of 50 bytes for 10 rows of step 12 \(120 bytes expected\)"):
        image_to_gray(10, 12, "mono8", 12, bytes(50))
    with pytest.raises(ImageEncodingError, match=r"image data of 240 bytes .* \(120 bytes expected\)"):
        image_to_gray(10, 12, "mono8", 12, bytes(240))           # twice the image: not one frame
    with pytest.raises(ImageEncodingError, match="image step 12 bytes is shorter than a row of 12 px x 3 channels"):
        image_to_gray(10, 12, "bgr8", 12, bytes(120))


def test_velocity_estimator_is_a_least_squares_slope():
    v = VelocityEstimator(0.5, min_samples=3)
    assert v.velocity() is None
    for k in range(10):
        v.add(k * 0.1, 2.0 + 0.37 * k * 0.1)
    assert v.velocity() == pytest.approx(0.37)
    assert len(v.samples) == 6  # only the last 0.5 s
    v.add(0.0, 0.0)  # time jumped back
    assert v.velocity() is None


def _ramp_speed(t):
    """0 until 0.2 s, then 1.85 m/s^2 up to 0.37 m/s at 0.4 s, then constant (an attack start)."""
    return np.clip((np.asarray(t) - 0.2) * 1.85, 0.0, 0.37)


def _ramp_x(t):
    t = np.asarray(t, dtype=float)
    a = np.clip(t - 0.2, 0.0, 0.2)
    return 1.85 * a ** 2 / 2 + 0.37 * np.clip(t - 0.4, 0.0, None)


def _best_delay(est, fps=30.0, t_end=1.2):
    """The delay d (s) that best explains an estimator's output on the noiseless ramp: its
    output at t compared with the true speed at t - d."""
    ts = np.arange(0.0, t_end, 1 / fps)
    out = []
    for t, x in zip(ts, _ramp_x(ts)):
        est.add(float(t), float(x))
        out.append(est.velocity())
    t, v = ts[2:], np.array(out[2:], dtype=float)
    delays = np.arange(0.0, 0.3, 0.005)
    rms = [np.sqrt(np.mean((v - _ramp_speed(t - d)) ** 2)) for d in delays]
    return float(delays[int(np.argmin(rms))]), v, t


def test_window_estimator_lags_half_its_window_and_the_kalman_filter_does_not():
    # a least-squares slope over a window is the speed at the window's middle: 0.15 s late for
    # 0.3 s (exact for a ramp); the Kalman filter reports the speed at the last measurement
    d_ls, _, _ = _best_delay(VelocityEstimator(0.3))
    assert d_ls == pytest.approx(0.15, abs=0.02)
    d_kf, v, t = _best_delay(KalmanVelocityEstimator(accel_noise=1.0, position_noise=0.001))
    assert d_kf <= 0.04
    # at constant speed both are exact (noiseless): the filter has no bias
    assert v[t > 0.9] == pytest.approx(0.37, abs=2e-3)


def test_kalman_velocity_noise_matches_its_riccati_covariance():
    # a machine moving as the filter's model says (speed a random walk of spectral density q),
    # seen at 30 Hz with white 1 mm noise: the spread of the filter's speed error must be the
    # steady-state covariance of the Riccati recursion, iterated here independently
    q, sigma, dt = 1.0, 0.001, 1 / 30.0
    F = np.array([[1.0, dt], [0.0, 1.0]])
    Q = q * np.array([[dt ** 3 / 3, dt ** 2 / 2], [dt ** 2 / 2, dt]])
    H = np.array([[1.0, 0.0]])
    P = np.eye(2)
    for _ in range(2000):
        Pp = F @ P @ F.T + Q
        K = Pp @ H.T / (H @ Pp @ H.T + sigma ** 2)
        P = (np.eye(2) - K @ H) @ Pp
    sd_theory = math.sqrt(P[1, 1])
    rng = np.random.default_rng(3)
    est = KalmanVelocityEstimator(q, sigma)
    L = np.linalg.cholesky(Q)
    state = np.array([0.0, 0.37])
    errs = []
    for k in range(20000):
        est.add(k * dt, state[0] + rng.normal(0.0, sigma))
        if k > 60:
            errs.append(est.velocity() - state[1])
        state = F @ state + L @ rng.standard_normal(2)
    assert abs(np.mean(errs)) < 0.1 * sd_theory
    assert np.std(errs) == pytest.approx(sd_theory, rel=0.1)
    assert est.speed_sd() == pytest.approx(sd_theory, rel=1e-3)


def test_kalman_velocity_stamps_gaps_and_parameters():
    v = KalmanVelocityEstimator(max_gap=0.5)
    assert v.add(0.0, 0.0) and v.velocity() is None
    assert v.add(0.1, 0.037) and v.velocity() is None       # two measurements: not yet a speed
    assert v.add(0.2, 0.074) and v.velocity() == pytest.approx(0.37, abs=1e-3)
    assert not v.add(0.2, 5.0)                               # repeated stamp: nothing added
    assert v.velocity() == pytest.approx(0.37, abs=1e-3)
    assert not v.add(0.1, 0.0)                               # backward: restarts from this sample
    assert v.velocity() is None and v.last_t == 0.1
    for k in range(2, 5):
        v.add(0.1 * k, 0.0)
    assert v.velocity() == pytest.approx(0.0, abs=1e-3)
    v.add(1.5, 1.0)                                          # after a 1.1 s gap: a new start, no speed
    assert v.velocity() is None
    for bad in ({"accel_noise": 0.0}, {"position_noise": float("nan")}, {"max_gap": -1.0}):
        with pytest.raises(ValueError, match="must be a finite number > 0"):
            KalmanVelocityEstimator(**bad)


def test_rendered_marker_moves_smoothly_below_a_pixel():
    # a camera pixel integrates light over its area, so a marker moved by 1/40 px moves its
    # detected corners by 1/40 px; one sample per pixel (supersample=1) puts the edges on the pixel
    # grid and the corners jump in steps (a sawtooth error of about 0.15 px sd, 1 mm at 1.6 m)
    from lhd_loading_ros.perception.aruco import project
    K, T_pc, tex = intrinsics(640, 480), transform(CAM_XYZ, CAMERA_RPY), marker_texture("DICT_4X4_50", 7)
    det = MarkerDetector("DICT_4X4_50", 7, SIZE)

    def mean_corner_error(supersample):
        out = []
        for j in range(40):     # 0.05 mm steps along x: 0.026 px each, 1 px in all
            T_cm = np.linalg.inv(T_pc) @ transform((-0.6 + j * 0.00005, 0.0, 0.35), (0, 0, 0))
            img = render(K, 640, 480, T_cm, tex, SIZE, np.random.default_rng(j), noise=0.0, blur=1,
                         supersample=supersample)
            out.append((det.detect(img) - project(K, T_cm, det.obj)).mean(axis=0))
        return np.array(out)

    area = mean_corner_error(8)
    point = mean_corner_error(1)
    assert np.abs(area.mean(axis=0)).max() < 0.02           # px: no bias
    assert area.std(axis=0).max() < 0.05                     # px: no pixel-locked pattern
    assert point.std(axis=0).max() > 2 * area.std(axis=0).max()


def test_marker_centre_is_where_the_diagonals_cross_not_the_corner_mean():
    from lhd_loading_ros.perception.aruco import diagonal_crossing, project
    K, T_pc = intrinsics(640, 480), transform(CAM_XYZ, CAMERA_RPY)
    # a marker tilted 40 deg about y and far off the camera axis: strong perspective
    T_cm = np.linalg.inv(T_pc) @ transform((-0.1, 0.3, 0.35), (0.0, math.radians(40), 0.2))
    s = SIZE / 2
    corners = project(K, T_cm, np.array([[-s, s, 0], [s, s, 0], [s, -s, 0], [-s, -s, 0]]))
    centre = project(K, T_cm, np.zeros((1, 3)))[0]
    assert np.allclose(diagonal_crossing(corners), centre, atol=1e-9)
    assert np.linalg.norm(corners.mean(axis=0) - centre) > 0.1      # px: the mean is not the centre
    with pytest.raises(ValueError, match="degenerate"):
        diagonal_crossing(np.zeros((4, 2)))
    with pytest.raises(ValueError, match="degenerate"):                # a self-crossing (bow-tie) order
        diagonal_crossing(corners[[0, 2, 1, 3]])


def test_ray_through_the_centre_meets_the_plane_where_the_marker_is():
    """Independent check: OpenCV projects the marker's corners through a distorting lens; the
    ray through their undistorted diagonals' crossing, met with the marker's height, must give
    the marker's centre. Crossing the diagonals in the distorted image instead would be off."""
    import cv2

    from lhd_loading_ros.perception.aruco import diagonal_crossing, marker_centre_ray, position_on_plane
    T_pc = transform(CAM_XYZ, CAMERA_RPY)
    D = np.array([-0.12, 0.05, 0.001, -0.002, 0.0])
    cam = CameraModel(intrinsics(640, 480), D)
    T_cp = np.linalg.inv(T_pc)
    rvec, _ = cv2.Rodrigues(T_cp[:3, :3])
    s = SIZE / 2
    sq = np.array([[-s, s, 0], [s, s, 0], [s, -s, 0], [-s, -s, 0]])
    naive = []
    for xyz, rpy in (((-0.9, 0.2, 0.35), (0, 0, 0)), ((-0.2, -0.3, 0.35), (0, 0, 0.5)),
                     ((-0.5, 0.0, 0.5), (0.1, -0.1, 0)), ((0.1, 0.25, 0.0), (0, 0, -0.3))):
        T = transform(xyz, rpy)
        uv, _ = cv2.projectPoints(sq @ T[:3, :3].T + T[:3, 3], rvec, T_cp[:3, 3], cam.K, D)
        got = position_on_plane(marker_centre_ray(uv.reshape(4, 2), cam), T_pc, xyz[2])
        assert np.allclose(got, xyz, atol=1e-6), (got, xyz)
        c = cv2.undistortPoints(diagonal_crossing(uv.reshape(4, 2)).reshape(1, 1, 2), cam.K, D).reshape(2)
        naive.append(np.linalg.norm(position_on_plane(c, T_pc, xyz[2]) - xyz))
    assert max(naive) > 1e-4          # m: crossing the distorted diagonals would be 0.1 mm and more off
    # a plane above the camera is behind the ray: no position, not a mirrored one
    assert position_on_plane(np.zeros(2), T_pc, 2.0) is None


def test_position_from_the_ray_is_ten_times_steadier_than_solvepnp():
    """On rendered frames of a drive (noise 4 grey levels, blur): the marker's x from the ray
    through its centre at the known height against solvePnP's x, both against the truth."""
    from lhd_loading_ros.perception.aruco import marker_centre_ray, position_on_plane
    rng = np.random.default_rng(4)
    K, T_pile_cam, t, truth, frames = drive_sequence(rng)
    det = MarkerDetector("DICT_4X4_50", 7, SIZE)
    cam = CameraModel(K, np.zeros(5))
    e_pnp, e_ray = [], []
    for img, T_pm in zip(frames, truth):
        c = det.detect(img)
        e_pnp.append((T_pile_cam @ det.pose(c, cam))[0, 3] - T_pm[0, 3])
        e_ray.append(position_on_plane(marker_centre_ray(c, cam), T_pile_cam, 0.35)[0] - T_pm[0, 3])
    e_pnp, e_ray = np.array(e_pnp), np.array(e_ray)
    rms = lambda e: float(np.sqrt(np.mean(e ** 2)))   # noqa: E731
    print(f"x error RMS: ray {rms(e_ray) * 1000:.2f} mm, solvePnP {rms(e_pnp) * 1000:.2f} mm")
    assert rms(e_ray) < 0.0005, rms(e_ray)             # m: a fraction of a millimetre
    assert rms(e_ray) < rms(e_pnp) / 10, (rms(e_ray), rms(e_pnp))


def test_geometry_helpers():
    R = rpy_matrix(0.1, -0.2, 0.3)
    assert np.allclose(R @ R.T, np.eye(3)) and np.isclose(np.linalg.det(R), 1.0)
    q = quaternion_xyzw(rpy_matrix(0, 0, math.pi / 2))
    assert q == pytest.approx((0, 0, math.sqrt(0.5), math.sqrt(0.5)))
    assert np.allclose(apply(transform((1, 2, 3), (0, 0, 0)), np.zeros((1, 3))), [[1, 2, 3]])


@pytest.mark.parametrize("alpha_deg", [15.0, 20.0, 25.0, 30.0])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_slope_error_below_1_degree(alpha_deg, seed):
    rng = np.random.default_rng(seed)
    r, amin, inc, rpy = synthetic_scan(math.radians(alpha_deg), rng, noise=0.01, outliers=0.1)
    pts = scan_points_pile(r, amin, inc, (0.6, 0.0, 1.6), rpy)
    # the scene really has floor and back-wall points
    assert (pts[:, 2] < 0.02).sum() > 20 and (pts[:, 0] > 0.68 / math.tan(math.radians(alpha_deg))).sum() > 20
    f = fit_slope(pts, np.random.default_rng(seed))
    assert abs(math.degrees(f.alpha) - alpha_deg) < 1.0
    assert abs(f.toe_x) < 0.03
    assert f.residual < 0.015


def test_too_few_points_is_an_error_not_a_guess():
    rng = np.random.default_rng(0)
    with pytest.raises(TooFewPoints, match="need at least 30"):
        fit_slope(np.array([[0.1, 0.0, 0.05]] * 5), rng)
    flat = np.column_stack([np.linspace(0, 2, 200), np.zeros(200), np.full(200, 0.3)])  # no plausible face
    with pytest.raises(TooFewPoints):
        fit_slope(flat, rng)


def test_scan_to_points_drops_invalid_ranges():
    pts = scan_to_points(0.0, math.pi / 2, [1.0, float("inf"), 0.01, 2.0], 0.05, 10.0)
    assert np.allclose(pts, [[1.0, 0.0, 0.0], [0.0, -2.0, 0.0]], atol=1e-12)  # angles 0 and 3 pi / 2


def test_scan_header_checks_by_hand():
    """720 beams over 180 deg: the last beam lies at -pi/2 + 719 * pi/720 = pi/2 - pi/720."""
    inc = math.pi / 720
    amin = -math.pi / 2
    ok = dict(angle_min=amin, angle_max=amin + 719 * inc, angle_increment=inc, n=720, range_min=0.05, range_max=30.0)
    assert scan_problem(**ok) is None
    assert scan_problem(**{**ok, "angle_max": math.pi / 2}) is None          # one increment further: allowed
    assert scan_problem(**ok, n_intensities=720) is None
    assert "720 ranges but 719 intensities" in scan_problem(**ok, n_intensities=719)
    assert "720 ranges but 1440 intensities" in scan_problem(**ok, n_intensities=1440)
    assert "disagrees with itself" in scan_problem(**{**ok, "angle_max": amin + 721 * inc})
    assert "angle_increment = 0" in scan_problem(**{**ok, "angle_increment": 0.0, "angle_max": amin})
    assert scan_problem(**{**ok, "range_max": math.inf}) is None
    assert "expected finite" in scan_problem(**{**ok, "range_min": math.nan})


def test_perception_benchmark_runs():
    from lhd_loading_ros.cli.bench_perception import aruco_fps, slope_fit_ms

    assert aruco_fps(320, 240, n_frames=5, reps=1) > 1.0
    assert slope_fit_ms(reps=3) > 0.0


@pytest.mark.parametrize("alpha_deg", [15.0, 20.0, 25.0, 30.0, 40.0])
def test_draw_point_clutter_gives_the_same_slope(alpha_deg):
    """Roof at 2 m, the brow and the drawbell's 45 deg wall above the pile (a line of plausible
    pile slope, with more points than the face), the machine and its heaped bucket before the
    toe: the fit ignores them (before the robust fit it returned the drawbell's 45 deg)."""
    from lhd_loading_ros.perception.synthetic import DrawPoint

    full = dict(n=1440, angle_min=-math.pi, angle_max=math.pi * (1 - 1 / 720))
    for seed in range(3):
        r, amin, inc, rpy = synthetic_scan(math.radians(alpha_deg), np.random.default_rng(seed))
        clean = fit_slope(scan_points_pile(r, amin, inc, (0.6, 0.0, 1.6), rpy), np.random.default_rng(seed))
        r, amin, inc, rpy = synthetic_scan(math.radians(alpha_deg), np.random.default_rng(seed), clutter=DrawPoint(),
                                           **full)
        pts = scan_points_pile(r, amin, inc, (0.6, 0.0, 1.6), rpy)
        assert (pts[:, 2] > 1.8).sum() > 300            # the roof really is in view
        f = fit_slope(pts, np.random.default_rng(seed))
        assert abs(math.degrees(f.alpha - clean.alpha)) < 1.0 and abs(math.degrees(f.alpha) - alpha_deg) < 1.0


def test_no_pile_and_out_of_range_are_named():
    from lhd_loading_ros.perception.slope import SlopeOutOfRange
    from lhd_loading_ros.perception.synthetic import DrawPoint

    r, amin, inc, rpy = synthetic_scan(0.3, np.random.default_rng(0), h=0.0, back_x=1.5, clutter=DrawPoint(),
                                       n=1440, angle_min=-math.pi, angle_max=math.pi * (1 - 1 / 720))
    with pytest.raises(TooFewPoints):
        fit_slope(scan_points_pile(r, amin, inc, (0.6, 0.0, 1.6), rpy), np.random.default_rng(0))
    s = (-0.3, 0.0, 1.6)    # in front of the toe: a steep face is hidden from above the pile
    r, amin, inc, rpy = synthetic_scan(math.radians(62.0), np.random.default_rng(0), sensor_xyz=s,
                                       angle_min=-math.radians(120), angle_max=math.radians(10))
    with pytest.raises(SlopeOutOfRange, match=r"slope 6[12]\.\d deg outside \[5, 50\]"):
        fit_slope(scan_points_pile(r, amin, inc, s, rpy), np.random.default_rng(0))


@pytest.mark.parametrize("n_d, ok", [(0, True), (3, False), (4, True), (5, True), (8, True), (12, True), (14, True),
                                     (6, False)])
def test_camera_info_distortion_lengths(n_d, ok):
    K = intrinsics(640, 480).ravel()
    if ok:
        cam = CameraModel.from_camera_info(K, [0.01] * n_d, 640, 480)
        assert len(cam.D) == (n_d or 5) and (cam.width, cam.height) == (640, 480)
    else:
        with pytest.raises(ValueError, match=f"{n_d} distortion coefficients; expected one of 0, 4, 5, 8, 12, 14"):
            CameraModel.from_camera_info(K, [0.01] * n_d)


@pytest.mark.parametrize("k, needle", [
    ([math.nan] + [0.0] * 8, "K has NaN or inf"),
    ([0.0] * 8 + [1.0], "focal lengths fx=0, fy=0; expected > 0"),
    ([500.0, 0, 320, 0, 500, 240, 0, 0, 0], "last row"),
    ([500.0] * 4, "K has 4 elements; expected 9"),
])
def test_camera_info_bad_intrinsics(k, needle):
    with pytest.raises(ValueError, match=re.escape(needle)):
        CameraModel.from_camera_info(k, [])


def test_velocity_estimator_repeated_and_backward_stamps():
    v = VelocityEstimator(1.0)
    for k in range(4):
        assert v.add(k * 0.1, 0.37 * k * 0.1)
    assert not v.add(3 * 0.1, 5.0)               # repeated stamp: nothing added
    assert v.velocity() == pytest.approx(0.37)
    assert not v.add(0.1, 0.0)                   # backward: the window restarts from this sample
    assert v.velocity() is None and len(v.samples) == 1


def test_two_markers_of_the_machines_id_are_refused_not_picked_by_opencvs_order():
    """A spare or calibration marker of the same id in view (a review, 2026-11-29, twelfth session): detect
    took OpenCV's first, whose order changes from frame to frame, and the node published v_x of +-19 m/s, or
    the spare's standstill, as measured. Two in one frame is ambiguous: refused; one alone is found."""
    from lhd_loading_ros.perception.aruco import AmbiguousMarkerError

    rng = np.random.default_rng(5)
    K = intrinsics(640, 480)
    T_cam_pile = np.linalg.inv(transform(CAM_XYZ, CAMERA_RPY))
    tex = marker_texture("DICT_4X4_50", 7)
    a, b = drive_poses(np.array([0.0, 0.0]), -0.75, 0.0)[0], drive_poses(np.array([0.0, 0.0]), -0.30, 0.0)[0]
    img_a = render(K, 640, 480, T_cam_pile @ a, tex, SIZE, rng, noise=2.0, blur=1)
    img_b = render(K, 640, 480, T_cam_pile @ b, tex, SIZE, rng, noise=2.0, blur=1)
    det = MarkerDetector("DICT_4X4_50", 7, SIZE)
    assert det.detect(img_a) is not None and det.detect(img_b) is not None
    both = np.minimum(img_a, img_b)                     # dark markers on a light floor: both in one frame
    with pytest.raises(AmbiguousMarkerError, match="2 markers of id 7 in view"):
        det.detect(both)
    assert MarkerDetector("DICT_4X4_50", 8, SIZE).detect(both) is None     # another id: still none
