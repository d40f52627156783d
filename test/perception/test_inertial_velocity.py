"""The camera + accelerometer speed filter (perception.aruco.InertialVelocityEstimator) and the
accelerometer's geometry (forward_acceleration; the twin's imu_specific_force), against closed
forms written here: a machine that drives and stops against the pile, a biased sensor, an IMU
that goes silent, and gravity on a pitched machine."""
import math

import numpy as np
import pytest

from lhd_loading_ros.perception.aruco import (GravityCheck, InertialVelocityEstimator, KalmanVelocityEstimator,
                                              forward_acceleration)
from lhd_sim_node.sim_sensors import imu_specific_force

G = 9.81
FPS, IMU_HZ = 30.0, 50.0


def stop_profile(t):
    """x(t), v(t) of a machine at 0.30 m/s that meets the pile at t = 1 s and stops in 0.1 s at a
    constant 3 m/s^2, stands 0.4 s, then pushes on at 1 m/s^2 (closed form, piecewise)."""
    v0, t_hit, dec, t_go, acc = 0.30, 1.0, 3.0, 1.5, 1.0
    t_stop = t_hit + v0 / dec
    if t <= t_hit:
        return v0 * t, v0
    x_hit = v0 * t_hit
    if t <= t_stop:
        s = t - t_hit
        return x_hit + v0 * s - 0.5 * dec * s * s, v0 - dec * s
    x_stop = x_hit + v0 * v0 / (2 * dec)
    if t <= t_go:
        return x_stop, 0.0
    s = t - t_go
    return x_stop + 0.5 * acc * s * s, acc * s


def imu_samples(t_end, bias=0.0, noise=0.0, rng=None, t_from=0.0):
    """The mean acceleration over each 20 ms (what an anti-aliased IMU gives): the change of the
    exact speed over the interval, plus a bias and white noise."""
    out = []
    k = int(round(t_from * IMU_HZ)) + 1
    while k / IMU_HZ <= t_end + 1e-9:
        t1, t0 = k / IMU_HZ, (k - 1) / IMU_HZ
        a = (stop_profile(t1)[1] - stop_profile(t0)[1]) * IMU_HZ + bias
        if noise:
            a += rng.normal(0.0, noise)
        out.append((t1, a))
        k += 1
    return out


def run(est, t_end, imu, pos_noise=0.0005, seed=1):
    """Feed the estimator the camera (30 fps, white position noise) and the IMU samples in the
    order they arrive (a sample before the frame of its instant); (t, v_est, v_true) per frame."""
    rng = np.random.default_rng(seed)
    imu = list(imu)
    out, j = [], 0
    n = int(t_end * FPS)
    for k in range(n + 1):
        t = k / FPS
        if hasattr(est, "add_accel"):
            while j < len(imu) and imu[j][0] <= t + 1e-9:
                est.add_accel(*imu[j])
                j += 1
        x, v = stop_profile(t)
        est.add(t, x + rng.normal(0.0, pos_noise))
        ve = est.velocity()
        if ve is not None:
            out.append((t, ve, v))
    return out


def rms(rows, t0=-1.0, t1=1e9):
    e = [ve - v for t, ve, v in rows if t0 <= t <= t1]
    return math.sqrt(float(np.mean(np.square(e))))


def test_without_an_accelerometer_it_is_the_constant_velocity_filter():
    cv = KalmanVelocityEstimator(1.0, 0.0005, max_gap=0.5)
    iv = InertialVelocityEstimator(1.0, 0.0005, max_gap=0.5)
    a, b = run(cv, 3.0, []), run(iv, 3.0, [])
    assert len(a) == len(b) > 80
    assert max(abs(r[1] - s[1]) for r, s in zip(a, b)) < 1e-12
    assert iv.inertial_s == 0.0 and iv.blind_s == pytest.approx(3.0, abs=1e-9)


def test_a_stop_against_the_pile_is_followed_as_it_happens():
    """The constant-velocity filter lags the 0.1 s stop by frames; integrating the accelerometer
    (biased 0.1 m/s^2, 0.05 m/s^2 noise) between frames does not."""
    rng = np.random.default_rng(7)
    imu = imu_samples(3.0, bias=0.1, noise=0.05, rng=rng)
    cv = run(KalmanVelocityEstimator(1.0, 0.0005, max_gap=0.5), 3.0, [])
    iv = run(InertialVelocityEstimator(1.0, 0.0005, max_gap=0.5, imu_accel_noise=0.01), 3.0, imu)
    around = (0.95, 1.8)      # the stop, the stand and the push that follows
    e_cv, e_iv = rms(cv, *around), rms(iv, *around)
    print(f"\nspeed RMS over the stop: constant-velocity {e_cv:.4f} m/s, with the accelerometer {e_iv:.4f} m/s")
    assert e_iv <= 0.01
    assert e_cv >= 3.0 * e_iv
    # and nowhere worse once started (past the first 0.3 s, where both learn the speed)
    assert rms(iv, 0.3) <= 0.01 and rms(iv, 0.3) < rms(cv, 0.3)


def test_the_bias_is_learned_from_the_camera():
    est = InertialVelocityEstimator(1.0, 0.0005, max_gap=0.5, imu_accel_noise=0.01)
    rows = run(est, 6.0, imu_samples(6.0, bias=0.3))
    assert est.bias_estimate() == pytest.approx(0.3, abs=0.05)
    assert rms(rows, 4.0) <= 0.015         # the camera's 0.5 mm noise is the floor then
    # a lost marker restarts x and v, not what was learned of the sensor
    est.reset()
    assert est.bias_estimate() == pytest.approx(0.3, abs=0.05)


def test_an_imu_that_goes_silent_falls_back_to_the_camera_alone():
    """Samples only until t = 1.2 s (during the stop): the filter holds the last one for
    accel_timeout, then runs as the constant-velocity filter; the speed is still followed."""
    imu = [s for s in imu_samples(3.0) if s[0] <= 1.2]
    est = InertialVelocityEstimator(1.0, 0.0005, max_gap=0.5, accel_timeout=0.1, hold=0.1)
    rows = run(est, 3.0, imu)
    assert est.blind_s == pytest.approx(3.0 - 1.3, abs=1.0 / FPS)
    assert est.inertial_s == pytest.approx(1.3, abs=1.0 / FPS)
    cv = run(KalmanVelocityEstimator(1.0, 0.0005, max_gap=0.5), 3.0, [])
    assert rms(rows, 2.0) == pytest.approx(rms(cv, 2.0), rel=0.5)     # the camera alone, as before


def test_segments_cover_the_interval_once():
    est = InertialVelocityEstimator(accel_timeout=0.05, hold=0.05)
    for t, a in ((0.02, 1.0), (0.04, 2.0), (0.20, 3.0)):        # a 160 ms gap before the third
        est.add_accel(t, a)
    seg = est._segments(0.0, 0.30)
    assert sum(dt for dt, _ in seg) == pytest.approx(0.30)
    # each sample over its 20 ms; the gap (0.04, 0.15] unknown; the third over (0.15, 0.20], held
    # for accel_timeout past its stamp, then unknown again
    assert [(round(dt, 9), a) for dt, a in seg] == [(0.02, 1.0), (0.02, 2.0), (0.11, None), (0.05, 3.0),
                                                    (0.05, 3.0), (0.05, None)]
    est.hold = 0.0                        # not held at all: unknown from the newest sample's stamp on
    assert [(round(dt, 9), a) for dt, a in est._segments(0.0, 0.30)][-2:] == [(0.05, 3.0), (0.1, None)]
    assert not est.add_accel(0.20, 1.0) and not est.add_accel(0.3, float("nan"))
    assert est.add_accel(0.10, 1.0) and len(est.accel) == 1          # back in time: another time line


def test_refuses_bad_noise():
    with pytest.raises(ValueError, match="imu_accel_noise"):
        InertialVelocityEstimator(imu_accel_noise=0.0)


@pytest.mark.parametrize("pitch_deg", [0.0, 10.0, -25.0])
@pytest.mark.parametrize("a_x", [0.0, 1.0, -3.0])
def test_gravity_on_a_pitched_machine_is_not_acceleration(pitch_deg, a_x):
    """Specific force of a machine pitched by theta about y (REP 103: nose down positive) and
    accelerating a_x along the floor, written by hand: R^T (a_x, 0, g) with R = Ry(theta)."""
    th = math.radians(pitch_deg)
    c, s = math.cos(th), math.sin(th)
    f = (c * a_x - s * G, 0.0, s * a_x + c * G)
    assert forward_acceleration(f, 0.0, th, 0.0) == pytest.approx(a_x, abs=1e-12)
    # the twin's accelerometer gives exactly that f for the quaternion of Ry(theta)
    q = (math.cos(th / 2), 0.0, math.sin(th / 2), 0.0)
    assert imu_specific_force(q, (a_x, 0.0, 0.0), G) == pytest.approx(f, abs=1e-12)
    # a 1 deg pitch error leaks g sin(1 deg) = 0.171 m/s^2
    assert forward_acceleration(f, 0.0, th + math.radians(1.0), 0.0) - a_x == pytest.approx(
        G * math.sin(math.radians(1.0)), abs=0.01 + 0.02 * abs(a_x))


def test_yaw_turns_the_acceleration_into_the_pile_frame():
    f = (1.0, 0.0, G)                     # level, accelerating 1 m/s^2 along its own x
    assert forward_acceleration(f, 0.0, 0.0, math.radians(90.0)) == pytest.approx(0.0, abs=1e-12)
    assert forward_acceleration(f, 0.0, 0.0, math.radians(60.0)) == pytest.approx(0.5, abs=1e-12)
    with pytest.raises(ValueError, match="not finite"):
        forward_acceleration((float("nan"), 0.0, G), 0.0, 0.0, 0.0)


def test_samples_that_arrive_after_the_image_are_not_lost():
    """Each image is processed 20 ms after its instant (render and detection, as in the twin). IMU
    samples that arrive 3 ms after theirs (the twin's median) serve the images in time; arriving
    35 ms after (a loaded machine), most come after the image they belong to: the filter then runs
    again from its state before a late sample's interval at the next image (better than without its
    kept states), but each image's newest 15-35 ms are unknown and run as the constant-velocity
    filter: with this 0.5 mm camera the gain then shrinks to that of the camera alone, never below."""
    rng = np.random.default_rng(11)
    imu = imu_samples(3.0, bias=0.1, noise=0.05, rng=rng)

    def feed(late, history=None):
        est = InertialVelocityEstimator(1.0, 0.0005, max_gap=0.5, imu_accel_noise=0.01)
        if history is not None:
            est.HISTORY_S = history
        cam_rng = np.random.default_rng(1)
        events = [(t + late, 0, t, a) for t, a in imu]
        events += [(k / FPS + 0.020, 1, k / FPS, None) for k in range(int(3.0 * FPS) + 1)]
        rows = []
        for _, kind, t, a in sorted(events):
            if kind == 0:
                est.add_accel(t, a)
            else:
                x, v = stop_profile(t)
                est.add(t, x + cam_rng.normal(0.0, 0.0005))
                if est.velocity() is not None:
                    rows.append((t, est.velocity(), v))
        return est, rows

    _, on_time = feed(0.003)
    est, late = feed(0.035)
    _, lost = feed(0.035, history=0.0)     # no states kept: a late sample only serves later images
    assert est.reruns > 50
    e_on, e_late, e_lost = rms(on_time, 0.3), rms(late, 0.3), rms(lost, 0.3)
    e_cv = rms(run(KalmanVelocityEstimator(1.0, 0.0005, max_gap=0.5), 3.0, []), 0.3)
    print(f"\nspeed RMS: samples in time {e_on:.4f}, 35 ms late {e_late:.4f} (not run again: {e_lost:.4f}), "
          f"camera alone {e_cv:.4f} m/s")
    assert e_on <= 0.01
    assert e_late < e_lost
    assert e_late <= e_cv


def test_an_image_that_waits_for_its_covering_sample_is_filtered_as_if_in_time():
    """The ArUco node's imu_accel_wait, played offline: each image is processed 5 ms after its
    instant, each IMU sample arrives 15 ms after its stamp (its interval's end), so an image's
    covering sample comes after it. Held back until that sample has come (awaits_sample: the stream
    is live but has not covered the image's instant), an image is filtered exactly as when every
    sample came first; filtered at once it is not, and is worse around the stop."""
    rng = np.random.default_rng(12)
    imu = imu_samples(3.0, bias=0.1, noise=0.05, rng=rng)

    def feed(wait, late=0.015, proc=0.005):
        est = InertialVelocityEstimator(1.0, 0.0005, max_gap=0.5, imu_accel_noise=0.01)
        cam_rng = np.random.default_rng(1)
        events = [(t + late, 0, t, a) for t, a in imu]
        events += [(k / FPS + proc, 1, k / FPS, None) for k in range(int(3.0 * FPS) + 1)]
        rows, waits, pending = [], 0, None     # pending: (deadline, t, x, v) of the image held back

        def finish(t, x, v):
            est.add(t, x)
            if est.velocity() is not None:
                rows.append((t, est.velocity(), v))

        for now, kind, t, a in sorted(events):
            if pending is not None and now >= pending[0]:     # the one-shot timer
                finish(*pending[1:])
                pending = None
            if kind == 0:
                est.add_accel(t, a)
                if pending is not None and t >= pending[1]:   # the covering sample came
                    finish(*pending[1:])
                    pending = None
                continue
            if pending is not None:                           # the previous image first
                finish(*pending[1:])
                pending = None
            x, v = stop_profile(t)
            x += cam_rng.normal(0.0, 0.0005)
            if wait > 0.0 and est.last_t is not None and est.awaits_sample(t, 0.2):
                pending = (now + wait, t, x, v)
                waits += 1
            else:
                finish(t, x, v)
        if pending is not None:
            finish(*pending[1:])
        return rows, waits

    ideal, _ = feed(0.0, late=-0.1)            # every sample before its image
    waited, n_waits = feed(0.025)
    at_once, _ = feed(0.0)
    assert n_waits > 0.9 * 3.0 * FPS - 5      # nearly every image waits (the sample is always 15 ms behind)
    assert [r[0] for r in waited] == [r[0] for r in ideal]
    assert max(abs(a[1] - b[1]) for a, b in zip(waited, ideal)) < 1e-12
    e_ideal, e_now = rms(ideal, 0.95, 1.5), rms(at_once, 0.95, 1.5)
    print(f"\nspeed RMS around the stop: waiting for the covering sample {e_ideal:.4f}, filtered at once {e_now:.4f}")
    assert e_now > 1.2 * e_ideal


def test_awaits_sample_only_for_a_live_stream_that_has_not_covered_the_instant():
    est = InertialVelocityEstimator(1.0, 0.0005)
    assert not est.awaits_sample(1.0, 0.2)               # no accelerometer at all
    est.add_accel(1.00, 0.0)
    assert est.awaits_sample(1.01, 0.2)                  # live, 10 ms not covered yet
    assert not est.awaits_sample(1.00, 0.2)              # covered up to its stamp
    assert not est.awaits_sample(0.99, 0.2)
    assert not est.awaits_sample(1.25, 0.2)              # newest sample 0.25 s old: the stream stopped


def test_a_sample_after_lost_ones_stands_for_its_own_period_only():
    """A 50 Hz stream that loses four samples (a node too busy to take them): the sample after
    the gap is the mean over ITS 20 ms, not over the 100 ms since the last one received, so it
    covers at most 1.5 periods (30 ms) back; the rest of the gap runs as the constant-velocity
    filter. Without the stream's period (fewer than 4 intervals) the old rule, accel_timeout."""
    est = InertialVelocityEstimator(accel_timeout=0.2, hold=0.0)
    for k in range(1, 11):
        est.add_accel(k * 0.02, 0.0)                  # 0.02 .. 0.20
    est.add_accel(0.30, 5.0)                          # 0.22 .. 0.28 lost; a 5 m/s^2 push in (0.28, 0.30]
    seg = [(round(dt, 9), a) for dt, a in est._segments(0.20, 0.30)]
    assert seg == [(0.07, None), (0.03, 5.0)]
    dv = sum(dt * a for dt, a in est._segments(0.20, 0.30) if a is not None)
    assert dv == pytest.approx(0.15)                  # not 0.5: the push is spread over 30 ms, not 100
    few = InertialVelocityEstimator(accel_timeout=0.2, hold=0.0)
    for t, a in ((0.02, 0.0), (0.04, 0.0), (0.14, 5.0)):
        few.add_accel(t, a)
    assert [(round(dt, 9), a) for dt, a in few._segments(0.04, 0.14)] == [(0.1, 5.0)]


def rest_and_jump(est, frames, bias, jump_at=120, seed=4):
    """A machine at rest at x = -0.5, put to x = -1.6 at frame `jump_at` (30 fps), a 50 Hz
    accelerometer reading only its bias and noise; (velocity, bias estimate) after each frame."""
    rng = np.random.default_rng(seed)
    x, out = -0.5, []
    for k in range(1, frames + 1):
        t = k / FPS
        while not est.accel or est.accel[-1][0] < t:
            ta = (est.accel[-1][0] if est.accel else 0.0) + 0.02
            est.add_accel(ta, bias + rng.normal(0.0, 0.05))
        if k == jump_at:
            x = -1.6
        est.add(t, x + rng.normal(0.0, 0.0005))
        out.append((est.velocity(), est.bias_estimate()))
    return out


def test_a_machine_put_elsewhere_restarts_the_filter_and_keeps_its_bias():
    """Between attempts the machine is put back by hand (the twin: in one step) while the camera
    and the IMU run: x jumps 1.1 m in one frame and the accelerometer feels nothing. Read as
    motion, the jump would be 33 m/s and, with the accelerometer vouching that the machine did
    not accelerate, be learned as a bias of metres per second squared (twin run 37). The filter
    starts again at the new x: no speed for two frames, then 0, and the bias is the one it had."""
    bias = 0.1
    est = InertialVelocityEstimator(1.0, 0.0005, max_gap=0.5, imu_accel_noise=0.01)
    out = rest_and_jump(est, 240, bias)          # 8 s at rest, the bias learned; the jump at 4 s
    assert est.jumps == 1
    assert out[119][0] is None and out[120][0] is None       # the jump's frame and the next: no speed
    assert max(abs(v) for v, b in out[121:]) < 0.05          # at rest: the noise of the filter at rest (0.03)
    assert all(abs(b - bias) < 0.05 for v, b in out[200:])
    plain = InertialVelocityEstimator(1.0, 0.0005, max_gap=0.5, imu_accel_noise=0.01)
    plain.JUMP_M = math.inf                      # without the restart: the jump read as motion
    after = rest_and_jump(plain, 130, bias)[119:]
    assert max(abs(v) for v, b in after) > 5.0                # metres per second of a machine at rest
    assert max(abs(b - bias) for v, b in after) > 2.0         # and a bias of metres per second squared


def test_an_implausible_acceleration_is_refused():
    """|f| above 4 g (39.2 m/s^2) is no motion of the machine's rear frame: a fault (a 1000 m/s^2
    spike restarted the speed filter at every image, silently: a review). 3.5 g passes."""
    assert forward_acceleration((0.0, 0.0, 3.5 * G), 0.0, 0.0, 0.0) == pytest.approx(0.0, abs=1e-12)
    for f in ((1000.0, 0.0, G), (0.0, 0.0, 4.1 * G), (0.0, 0.0, 981.0)):   # the last: cm/s^2
        with pytest.raises(ValueError, match="beyond the 39.2 m/s\\^2"):
            forward_acceleration(f, 0.0, 0.0, 0.0)



def test_gravity_check_tells_m_s2_with_gravity_from_g_and_from_gravity_removed():
    """REP 145: linear_acceleration in m/s^2, gravity included. Figures by hand: at rest |f| = g;
    pitched 10 deg still g; braking at 5 m/s^2 sqrt(g^2 + 25) = 11.01; a 5 Hz vertical shake of
    5 m/s^2 averages out over its whole periods. An IMU in g reads 1.00, gravity removed 0."""
    rng = np.random.default_rng(0)

    def feed(f_of_t, t0=0.0, n=50, hz=50.0, noise=0.05):
        chk = GravityCheck()
        for k in range(n):
            t = t0 + k / hz
            chk.add(t, np.asarray(f_of_t(t)) + rng.normal(0.0, noise, 3))
        return chk

    ok = [lambda t: (0.0, 0.0, G),
          lambda t: imu_specific_force(np.array([math.cos(math.radians(5)), 0.0, math.sin(math.radians(5)), 0.0]),
                                       (0.0, 0.0, 0.0)),
          lambda t: (-5.0, 0.0, G),
          lambda t: (0.0, 0.0, G + 5.0 * math.sin(2 * math.pi * 5.0 * t))]
    for f in ok:
        chk = feed(f)
        assert chk.problem() is None, chk.mean_norm
    assert abs(feed(ok[2], noise=0.0).mean_norm - math.hypot(5.0, G)) < 1e-9
    assert abs(feed(ok[1], noise=0.0).mean_norm - G) < 1e-6
    in_g = feed(lambda t: (0.0, 0.0, 1.0))
    assert "averages 1.00 m/s^2" in in_g.problem() and "reporting in g" in in_g.problem()
    removed = feed(lambda t: (0.3, 0.0, 0.0))
    assert "averages 0.3" in removed.problem() and "gravity removed" in removed.problem()
    # judged once ten samples span half a second: not 9 at 50 Hz, nor 50 at 100 Hz (0.49 s) or 200 Hz
    assert feed(ok[0], n=9).mean_norm is None and "not judged yet" in feed(ok[0], n=9).problem()
    assert feed(ok[0], n=50, hz=100.0).mean_norm is None
    assert feed(ok[0], n=51, hz=100.0).mean_norm is not None and feed(ok[0], n=51, hz=100.0).problem() is None
    assert feed(ok[0], n=50, hz=200.0).mean_norm is None
    # a second's window: an IMU switched to g is caught within it, and one set right recovers
    chk = feed(ok[0])
    for k in range(50):
        chk.add(1.0 + k / 50.0, (0.0, 0.0, 1.0))
    assert chk.problem() is not None
    for k in range(50):
        chk.add(2.0 + k / 50.0, (0.0, 0.0, G))
    assert chk.problem() is None
    # a time line that restarts (a bag loop) forgets the old samples: judged again from scratch
    chk.add(0.5, (0.0, 0.0, G))
    assert chk.mean_norm is not None and len(chk.samples) == 1
