"""The twin node (lhd_sim_node/twin_node.py) and the real bridge node, both as separate processes
over real DDS, the bridge on the twin's pseudo-terminal as on the machine's serial port:
truth, sensors and markers flow; a wheel command on /lhd/cmd drives the simulated machine at
set-point x wheel radius on the flat before the pile; the bridge's command timeout stops it; the
bridge's joint states and load-cell mass are the simulator's; an ended attempt on /lhd/episode
and ~/reset make new piles; the device's own watchdog stops the machine when the bridge dies."""
import math
import os
import signal
import time

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue  # noqa: E402
from geometry_msgs.msg import PointStamped  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from sensor_msgs.msg import CameraInfo, Image, Imu, JointState, LaserScan  # noqa: E402
from std_msgs.msg import Float64, Float64MultiArray  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402
from visualization_msgs.msg import MarkerArray  # noqa: E402

from lhd_loading_ros.perception.aruco import forward_acceleration, roll_pitch  # noqa: E402
from lhd_loading_ros.ros.qos import LATCHED_QOS, MEASUREMENT_QOS, STATUS_QOS  # noqa: E402
from lhd_loading_ros.task.zones import Zones  # noqa: E402
from rosutil import RosProcess, init_ros, shutdown_ros, spin_until  # noqa: E402

# a whole stack in real time: alone, in `make test-stack` (test/conftest.py)
SERIAL = True

WHEEL_RADIUS = 0.137        # m, config machine.wheel_radius
SLOPES = (20.0, 25.0)


@pytest.fixture(scope="module")
def ros():
    init_ros()
    yield
    shutdown_ros()


class Rig:
    def __init__(self, tmp_path):
        self.link = str(tmp_path / "twin_due")
        self.twin = RosProcess("lhd_sim_node.twin_node", {
            "link": self.link, "start_pose": "approach", "d_attack": 0.8, "seed": 3,
            "slopes_deg": ",".join(f"{s:g}" for s in SLOPES), "material": "homogeneous", "reset_delay": 0.5,
            "weigh_timeout": 2.5, "camera_fps": 10.0, "lidar_hz": 4.0, "markers_hz": 4.0, "imu_hz": 20.0,
            "imu_noise_deg": 0.1}, tmp_path / "twin.log")
        self.node = rclpy.create_node("twin_test")
        self.got = {k: [] for k in ("odom", "mass", "tip", "truth_js", "slope", "zones", "drift", "js", "lc",
                                    "img", "info", "scan", "markers", "diag", "imu")}
        n, g = self.node, self.got

        def rec(key, f=lambda m: m):
            return lambda m: g[key].append((time.monotonic(), f(m)))

        n.create_subscription(Odometry, "/lhd/twin/truth/odom", rec("odom"), MEASUREMENT_QOS)
        n.create_subscription(Float64, "/lhd/twin/truth/loaded_mass", rec("mass", lambda m: m.data), MEASUREMENT_QOS)
        n.create_subscription(PointStamped, "/lhd/twin/truth/tip", rec("tip"), MEASUREMENT_QOS)
        n.create_subscription(JointState, "/lhd/twin/truth/joint_states", rec("truth_js"), MEASUREMENT_QOS)
        n.create_subscription(Float64MultiArray, "/lhd/twin/truth/drift", rec("drift", lambda m: list(m.data)),
                              MEASUREMENT_QOS)
        n.create_subscription(Float64, "/lhd/twin/truth/slope", rec("slope", lambda m: m.data), LATCHED_QOS)
        n.create_subscription(Float64MultiArray, "/lhd/twin/truth/zones", rec("zones", lambda m: list(m.data)),
                              LATCHED_QOS)
        n.create_subscription(JointState, "/lhd/joint_states", rec("js"), MEASUREMENT_QOS)
        n.create_subscription(Float64, "/lhd/load_cell/mass", rec("lc", lambda m: m.data), MEASUREMENT_QOS)
        n.create_subscription(Image, "/camera/image_raw", rec("img"), MEASUREMENT_QOS)
        n.create_subscription(CameraInfo, "/camera/camera_info", rec("info"), MEASUREMENT_QOS)
        n.create_subscription(LaserScan, "/scan", rec("scan"), MEASUREMENT_QOS)
        n.create_subscription(MarkerArray, "/lhd/twin/markers", rec("markers"), MEASUREMENT_QOS)
        n.create_subscription(DiagnosticArray, "/diagnostics", rec("diag"), 20)
        n.create_subscription(Imu, "/lhd/imu", rec("imu"), MEASUREMENT_QOS)
        self.pub_cmd = n.create_publisher(Float64MultiArray, "/lhd/cmd", 1)
        self.pub_episode = n.create_publisher(DiagnosticStatus, "/lhd/episode", STATUS_QOS)
        self.reset_client = n.create_client(Trigger, "/lhd_twin/reset")
        assert spin_until(n, lambda: os.path.exists(self.link) and g["odom"], timeout=30.0), \
            "the twin did not come up:\n" + self.twin.log()
        self.bridge = RosProcess("lhd_hw_bridge.bridge_node", {"port": self.link}, tmp_path / "bridge.log")
        assert spin_until(n, lambda: len(g["js"]) > 5, timeout=20.0), "no joint states from the bridge:\n" + \
            self.bridge.log() + self.twin.log()
        self.drive([0.0, 0.0, 0.0], 0.2)     # the fresh start the bridge waits for (the mux's idle zeros)

    def spin(self, seconds):
        spin_until(self.node, lambda: False, timeout=seconds)

    def drive(self, data, seconds, zero_first=True):
        # one zero first, as the command mux's idle zeros between two drives: the bridge moves the machine again
        # after a silence of the device (a test process starved on a loaded machine) only after an all-zero command.
        # zero_first=False where the test checks that the machine stays stopped without a fresh zero (the e-stop's
        # release): that zero, arriving after the bridge saw the release, would be the fresh start (CI 2026-12-01)
        if zero_first:
            self.pub_cmd.publish(Float64MultiArray(data=[0.0, 0.0, 0.0]))
            self.spin(0.02)
        t_end = time.monotonic() + seconds
        while time.monotonic() < t_end:
            self.pub_cmd.publish(Float64MultiArray(data=list(data)))
            self.t_pub = time.time()        # the last command sent, on the system clock (the stamps')
            self.spin(0.05)

    def last(self, key):
        return self.got[key][-1][1]

    def twin_status(self, what):
        """The latest /diagnostics status of the twin named `what`, as a dict (with 'message')."""
        for _, arr in reversed(self.got["diag"]):
            for st in arr.status:
                if st.name == f"/lhd_twin: {what}":
                    return {"message": st.message, "level": st.level, **{kv.key: kv.value for kv in st.values}}
        return None

    def close(self):
        self.node.destroy_node()
        rc_b = self.bridge.stop()
        rc_t = self.twin.stop()
        return rc_b, rc_t


@pytest.fixture(scope="module")
def rig(ros, tmp_path_factory):
    r = Rig(tmp_path_factory.mktemp("twin"))
    yield r
    rc_b, rc_t = r.close()
    assert rc_t == 0, r.twin.log()


def test_truth_sensors_and_markers_flow(rig):
    g = rig.got
    assert spin_until(rig.node, lambda: g["slope"] and g["zones"] and g["img"] and g["info"] and g["scan"]
                      and g["markers"] and g["tip"] and g["drift"] and g["mass"] and g["truth_js"], timeout=10.0), \
        {k: len(v) for k, v in g.items()}
    assert rig.last("slope") == pytest.approx(math.radians(SLOPES[0]), abs=1e-12)   # pile 0: the first slope
    z = Zones.from_list(rig.last("zones"))                     # 8 valid fields, as the end-zone node's
    assert 0.0 < z.x_min < z.x_max
    # approach pose: at rest, the tip d_attack = 0.8 m before the toe, nothing loaded
    tip = rig.last("tip").point
    assert tip.x == pytest.approx(-0.8, abs=0.01) and rig.last("mass") == 0.0 and rig.last("drift") == [0.0, 0.0]
    img, info = rig.last("img"), rig.last("info")
    assert (img.encoding, img.width, img.height, len(img.data)) == ("mono8", 640, 480, 640 * 480)
    assert info.k[0] == pytest.approx(0.94 * 640) and info.k[2] == 320.0 and info.width == 640
    scan = rig.last("scan")
    r = np.array(scan.ranges)
    assert len(r) == 720 and not np.isnan(r).any() and np.isfinite(r).sum() > 300
    ma = rig.last("markers")
    assert {m.ns for m in ma.markers} >= {"pile", "zones", "tip", "fee"}
    # the truth's timing: 50 Hz odometry
    t = [tt for tt, _ in g["odom"][-30:]]
    assert 30.0 < (len(t) - 1) / (t[-1] - t[0]) < 70.0
    # the IMU (imu_hz 20): the machine's true orientation within its noise (0.1 deg sd): the angle
    # between the two quaternions, 2 acos |<q1, q2>|, under 0.6 deg (6 sd of each of two axes)
    assert spin_until(rig.node, lambda: len(g["imu"]) > 3, timeout=5.0)
    q_imu, q_true = rig.last("imu").orientation, rig.last("odom").pose.pose.orientation
    dot = abs(sum(a * b for a, b in zip((q_imu.w, q_imu.x, q_imu.y, q_imu.z), (q_true.w, q_true.x, q_true.y, q_true.z))))
    assert math.degrees(2 * math.acos(min(1.0, dot))) < 0.6
    # its accelerometer at rest on the level floor: the specific force (0, 0, +g), within the
    # bias (<= 0.1 m/s^2 an axis) and 6 sd of its 0.05 m/s^2 noise
    la = rig.last("imu").linear_acceleration
    assert rig.last("imu").linear_acceleration_covariance[0] == pytest.approx(0.05 ** 2)
    assert (la.x, la.y, la.z) == (pytest.approx(0.0, abs=0.4), pytest.approx(0.0, abs=0.4), pytest.approx(9.81, abs=0.4))


def _stamp(m) -> float:
    return m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec


def test_wheel_command_drives_the_machine_and_the_command_timeout_stops_it(rig):
    g = rig.got
    x0 = rig.last("odom").pose.pose.position.x
    n_imu0 = len(g["imu"])

    def fwd(m):     # the acceleration along the floor, gravity removed with the IMU's own roll and pitch
        o, la = m.orientation, m.linear_acceleration
        return forward_acceleration((la.x, la.y, la.z), *roll_pitch(o.x, o.y, o.z, o.w), 0.0)

    bias_x = float(np.mean([fwd(m) for _, m in g["imu"][-20:]]))      # at rest: the bias
    t0 = time.monotonic()
    rig.drive([1.0, 0.0, 0.0], 2.0)                 # 1 rad/s at the wheels, arm held
    t_last, t_last_wall = time.monotonic(), rig.t_pub
    # the accelerometer saw the start: each sample (the mean over the interval since the previous
    # one), less the bias read at rest, is the truth's change of speed over that interval divided by
    # it, within its noise (0.05 m/s^2 sd; the start peaks at several times that)
    tv = sorted((_stamp(m), m.twist.twist.linear.x) for _, m in g["odom"])
    tt, vv = np.array([a for a, _ in tv]), np.array([b for _, b in tv])
    imu = sorted((m for _, m in g["imu"][n_imu0:] if m.linear_acceleration_covariance[0] != -1.0), key=_stamp)
    ti = np.array([_stamp(m) for m in imu])
    a_truth = np.diff(np.interp(ti, tt, vv)) / np.diff(ti)
    a_imu = np.array([fwd(m) for m in imu[1:]]) - bias_x
    assert len(imu) > 20 and np.max(a_truth) > 0.3, (len(imu), np.max(a_truth))
    err = a_imu - a_truth
    # the truth is v_x of /odom interpolated at the IMU's stamps, and that interpolation is itself wrong in two
    # places, neither of them the accelerometer's doing:
    # - where an odom sample is missing (a gap of more than twice the usual period around a stamp: odometry this
    #   process missed or the twin sent late), the interpolation spans the start's peak (several m/s^2 within
    #   0.1 s). Those samples are left out;
    # - where the acceleration changes within an odom interval (the start, the tyres' rocking after it), a straight
    #   line between two odom samples misses the speed by up to h |a2 - a1| / 4 (a step from a1 to a2 inside an
    #   interval of length h; a1, a2 read from the odom intervals either side, whose own slopes the interval's lies
    #   between). Divided by the IMU's interval (50 ms against odom's 20 ms), that is 0.3-0.4 m/s^2 at the start: the
    #   two onset samples alone took the RMS over all samples to 0.103 against a bound of 0.1 in one CI run
    #   (2026-12-02), the accelerometer within its noise everywhere else.
    # So: every sample with a resolved interpolation is within 6 sd of the noise (0.3 m/s^2) plus the truth's own
    # uncertainty there (the onset checked too: an accelerometer a sample late misses the 4 m/s^2 peak by far more),
    # and over the samples where that uncertainty is under one sd (at least 15), the RMS is within 2 sd of the noise.
    gaps = np.diff(tt)
    usual = 2.0 * float(np.median(gaps))
    j = np.clip(np.searchsorted(tt, ti), 1, len(tt) - 1)
    known = (tt[j] - tt[j - 1]) <= usual                       # per IMU stamp: the truth is resolved there
    valid = known[1:] & known[:-1]                              # per sample: both ends of its interval
    a_odom = np.diff(vv) / np.maximum(gaps, 1e-6)               # per odom interval: its mean acceleration
    k = j - 1                                                   # the odom interval each IMU stamp lies in
    a_here = a_odom[k]
    a_prev = a_odom[np.maximum(k - 1, 0)]
    a_next = a_odom[np.minimum(k + 1, len(a_odom) - 1)]
    e_v = gaps[k] / 4.0 * (np.abs(a_here - a_prev) + np.abs(a_next - a_here))      # m/s, per IMU stamp
    unc = (e_v[1:] + e_v[:-1]) / np.diff(ti)                    # m/s^2, per sample
    resolved = valid & (unc < 0.05)
    rms = math.sqrt(float(np.mean(err[resolved] ** 2))) if resolved.any() else math.inf
    print(f"\ntwin accelerometer: RMS {rms:.3f} m/s^2 against the truth over {int(resolved.sum())} of {len(err)} samples "
          f"(all: {math.sqrt(float(np.mean(err ** 2))):.3f}), largest |error| - truth's uncertainty "
          f"{float(np.max((np.abs(err) - unc)[valid])):.3f}, peak {np.max(a_truth):.2f}, largest odom gap "
          f"{1e3 * float(np.max(gaps)):.0f} ms")
    diag = (a_imu.round(3).tolist(), a_truth.round(3).tolist(), unc.round(3).tolist(),
            f"odom gaps ms: {np.round(1e3 * gaps, 1).tolist()}")
    assert resolved.sum() >= 15, (f"{int(resolved.sum())} of {len(err)} samples with a resolved truth", diag)
    assert np.all((np.abs(err) <= 0.3 + unc)[valid]), diag
    assert rms < 0.1, diag
    steady = [s for s in g["odom"] if t0 + 0.8 <= s[0] <= t_last]
    vx = [m.twist.twist.linear.x for _, m in steady]
    # on the flat before the pile the machine rolls at set-point x wheel radius: 1.0 x 0.137 m/s
    # (the median: a test process starved for 0.3 s on a loaded machine lets the bridge's timeout
    # brake the wheels for a moment, which is the bridge doing its job)
    assert float(np.median(vx)) == pytest.approx(1.0 * WHEEL_RADIUS, rel=0.1), (vx, rig.bridge.log()[-2000:])
    # the truth's pose and speed agree: the distance over each odom interval is the integral of v_x over
    # it. Summed over the usual intervals only: across a missing sample (a starved test process, 258 ms
    # once in CI) the bridge's command timeout may have braked the wheels and driven on again, which a
    # trapezoid over the gap cannot see (it counted 0.199 m where the machine moved 0.165 m)
    by_stamp = sorted(steady, key=lambda s: _stamp(s[1]))
    ts = np.array([_stamp(m) for _, m in by_stamp])
    xs = np.array([m.pose.pose.position.x for _, m in by_stamp])
    vs = np.array([m.twist.twist.linear.x for _, m in by_stamp])
    dt = np.diff(ts)
    regular = dt <= usual
    assert regular.sum() >= max(20, 0.75 * len(dt)), np.round(1e3 * dt, 1).tolist()
    moved = float(np.sum(np.diff(xs)[regular]))
    integral = float(np.sum((0.5 * (vs[1:] + vs[:-1]) * dt)[regular]))
    assert moved == pytest.approx(integral, rel=0.05), (moved, integral, np.round(1e3 * dt, 1).tolist())
    assert rig.last("tip").point.x < -0.4                    # still on the flat
    # the bridge's joint states carry the wheels: front wheels and the rear differential at the set-point
    # (the median over the steady window, as for v_x: one frame can catch the wheels in a transient,
    # 1.12 rad/s once on a loaded machine)
    js = [m for t, m in g["js"] if t0 + 0.8 <= t <= t_last]
    assert js
    assert float(np.median([m.velocity[2] for m in js])) == pytest.approx(1.0, abs=0.05)
    assert float(np.median([m.velocity[4] for m in js])) == pytest.approx(1.0, abs=0.05)
    # /lhd/cmd falls silent: the bridge sends stop frames after its 0.3 s timeout, the wheels brake.
    # Judged by the instant each state is of (its stamp, on the system clock), not by when this
    # process heard it: a starved test process hears a backlog of earlier states late
    assert spin_until(rig.node, lambda: any(_stamp(m) > t_last_wall + 2.0 for _, m in g["odom"]), 10.0)
    after = [(_stamp(m) - t_last_wall, m.twist.twist.linear.x) for _, m in g["odom"] if _stamp(m) > t_last_wall]
    profile = [(round(t, 3), round(v, 4)) for t, v in after]
    assert all(v > 0.08 for t, v in after if 0.0 < t < 0.25), profile      # not before the timeout
    # it stops within 0.3 s + 0.4 s, rocks on its tyres for about half a second, then rests
    assert next((t for t, v in after if abs(v) < 0.02), math.inf) < 0.3 + 0.4, profile
    rest = [v for t, v in after if t > 1.6]
    assert rest and all(abs(v) < 0.005 for v in rest), profile
    x1 = rig.last("odom").pose.pose.position.x
    # travelled: about 2 s x 0.137 m/s, plus the 0.3 s timeout's, less the start
    assert 0.2 < x1 - x0 < 0.4


def test_joint_states_and_load_cell_are_the_simulators(rig):
    g = rig.got
    # into the pile at full speed (until the lip is 0.15 m in, wherever the machine stood: the test
    # runs alone too), then dig: lift and curl at full speed
    t_end = time.monotonic() + 8.0
    rig.drive([2.7, 0.0, 0.0], 1.0)
    while rig.last("tip").point.x < 0.15 and time.monotonic() < t_end:
        rig.drive([2.7, 0.0, 0.0], 0.2)
    rig.drive([2.0, -0.191, 0.2], 1.5)
    rig.spin(0.8)                                       # timeout: everything stops and holds
    assert rig.last("tip").point.x > 0.0, "the bucket never reached the pile"
    n = len(g["js"]), len(g["truth_js"]), len(g["lc"]), len(g["mass"])
    rig.spin(0.5)
    js, truth = rig.last("js"), rig.last("truth_js")
    assert len(g["js"]) > n[0] and len(g["truth_js"]) > n[1]
    # the arm moved: the boom lifted (negative), the bucket curled (positive), in both
    assert truth.position[0] < -0.1 and truth.position[1] > 0.1
    # the bridge's joint states (through the serial frames) are the simulator's, at 1e-4 rad
    assert js.position[0] == pytest.approx(truth.position[0], abs=2e-4)
    assert js.position[1] == pytest.approx(truth.position[1], abs=2e-4)
    assert js.velocity[0] == pytest.approx(truth.velocity[0], abs=2e-3)
    assert js.velocity[1] == pytest.approx(truth.velocity[1], abs=2e-3)
    rear = 0.5 * (truth.velocity[4] + truth.velocity[5])
    assert js.velocity[4] == js.velocity[5] == pytest.approx(rear, abs=5e-3)
    # the load cell weighs the simulator's loaded mass (to the gram), something was loaded
    assert len(g["lc"]) > n[2] and len(g["mass"]) > n[3]
    m_truth, m_cell = rig.last("mass"), rig.last("lc")
    assert m_truth > 0.5
    assert m_cell == pytest.approx(m_truth, abs=1e-3)


def _status(state, episode, mass="nan"):
    st = DiagnosticStatus(name="supervisor", level=DiagnosticStatus.OK, message=state)
    st.values = [KeyValue(key="state", value=state), KeyValue(key="episode", value=str(episode)),
                 KeyValue(key="loaded_mass", value=mass)]
    return st


def test_ended_attempt_and_reset_service_make_new_piles(rig):
    g = rig.got
    n_slope = len(g["slope"])
    rig.pub_episode.publish(_status("running", 1))
    rig.spin(0.3)
    assert len(g["slope"]) == n_slope                   # a running attempt changes nothing
    t_end = time.monotonic()
    rig.pub_episode.publish(_status("success", 1))      # ended, not yet weighed: the pile stays
    for _ in range(4):
        rig.spin(0.25)
        rig.pub_episode.publish(_status("success", 1))  # (the supervisor republishes its status)
    assert len(g["slope"]) == n_slope
    rig.pub_episode.publish(_status("success", 1, "31.20"))   # weighed: a new pile
    assert spin_until(rig.node, lambda: len(g["slope"]) > n_slope, timeout=5.0), rig.twin.log()
    t_new = g["slope"][-1][0]
    assert t_new - t_end >= 1.0                        # after the weighing (and reset_delay)
    assert rig.last("slope") == pytest.approx(math.radians(SLOPES[1]), abs=1e-12)   # pile 1: the next slope
    rig.spin(0.5)
    assert rig.last("mass") == 0.0 and rig.last("tip").point.x == pytest.approx(-0.8, abs=0.01)
    assert spin_until(rig.node, lambda: g["lc"] and g["lc"][-1][1] == 0.0, timeout=2.0)
    rig.pub_episode.publish(_status("success", 1, "31.20"))   # the same status again (latched): no second reset
    rig.spin(1.0)
    assert len(g["slope"]) == n_slope + 1
    assert rig.reset_client.wait_for_service(timeout_sec=5.0)
    fut = rig.reset_client.call_async(Trigger.Request())
    assert spin_until(rig.node, fut.done, timeout=10.0)
    assert fut.result().success and "pile 2" in fut.result().message
    assert spin_until(rig.node, lambda: len(g["slope"]) > n_slope + 1, timeout=3.0)
    assert rig.last("slope") == pytest.approx(math.radians(SLOPES[0]), abs=1e-12)   # cycles back
    # an attempt nobody weighs (no load cell, no operator): a new pile weigh_timeout after its end
    n_slope = len(g["slope"])
    t_end = time.monotonic()
    rig.pub_episode.publish(_status("aborted", 2))
    assert spin_until(rig.node, lambda: len(g["slope"]) > n_slope, timeout=6.0), rig.twin.log()
    assert g["slope"][-1][0] - t_end >= 2.4
    # an attempt that ends unweighed, then ~/reset at once (`lhd up twin` after an attempt that never ran):
    # one new pile, and none weigh_timeout later (the reset ends the wait for the weighing)
    rig.pub_episode.publish(_status("aborted", 3))
    rig.spin(0.3)
    n_slope = len(g["slope"])
    fut = rig.reset_client.call_async(Trigger.Request())
    assert spin_until(rig.node, fut.done, timeout=10.0) and fut.result().success
    assert spin_until(rig.node, lambda: len(g["slope"]) > n_slope, timeout=3.0)
    for _ in range(14):                                  # 3.5 s > weigh_timeout 2.5 s, the status republished
        rig.pub_episode.publish(_status("aborted", 3))
        rig.spin(0.25)
    assert len(g["slope"]) == n_slope + 1, rig.twin.log()


def test_estop_button_holds_the_machine_and_release_needs_a_fresh_command(rig):
    """`estop:=true` at run time presses the simulated machine's button: the machine stops while
    /lhd/cmd still asks to drive, the device reports it (flag bit 2: the bridge's hw/status);
    on release the same stream restarts nothing (2026-11-30: it used to drive again at once); after an
    all-zero command (the fresh start) the machine drives again."""
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient

    g = rig.got
    status = []
    rig.node.create_subscription(DiagnosticStatus, "/lhd/hw/status", lambda m: status.append(
        {kv.key: kv.value for kv in m.values}), MEASUREMENT_QOS)
    client = AsyncParameterClient(rig.node, "lhd_twin")
    assert client.wait_for_services(timeout_sec=5.0)

    def set_estop(value):
        fut = client.set_parameters([Parameter("estop", value=value)])
        assert spin_until(rig.node, fut.done, timeout=5.0)
        assert fut.result().results[0].successful, fut.result().results[0].reason

    rig.drive([1.0, 0.0, 0.0], 0.8)
    # on a loaded machine (CI 2026-11-30 read -0.035 m/s after 0.8 s) a starved test process lets the bridge's
    # command timeout brake the wheels, and the bridge drives again only after a fresh zero: drive() sends one
    t_end = time.monotonic() + 3.0
    while rig.last("odom").twist.twist.linear.x <= 0.1 and time.monotonic() < t_end:
        rig.drive([1.0, 0.0, 0.0], 0.2)
    assert rig.last("odom").twist.twist.linear.x > 0.1
    set_estop(True)
    t_press = time.monotonic()
    rig.drive([1.0, 0.0, 0.0], 1.2)                     # still asked to drive
    held = [s for s in g["odom"] if s[0] > t_press + 0.6]
    assert held and all(abs(m.twist.twist.linear.x) < 0.01 for _, m in held)
    assert status and status[-1]["estop"] == "True" and status[-1]["drive_enabled"] == "False"
    set_estop(False)
    t_release = time.monotonic()
    rig.drive([1.0, 0.0, 0.0], 1.0, zero_first=False)    # motion only: no fresh zero since the release
    assert status[-1]["estop"] == "False"
    still = [s for s in g["odom"] if s[0] > t_release + 0.6]
    assert still and all(abs(m.twist.twist.linear.x) < 0.01 for _, m in still), [m.twist.twist.linear.x
                                                                                  for _, m in still]
    rig.drive([0.0, 0.0, 0.0], 0.2)                      # the fresh start
    rig.drive([1.0, 0.0, 0.0], 0.6)
    # as at the start of this test: on a loaded machine (CI 2026-12-01: still -0.03 m/s 0.8 s into this drive, moving
    # only at its end) a starved test process lets the bridge's 0.3 s command timeout brake the wheels, and the bridge
    # drives again only after another fresh zero, which each drive() sends; a machine that never drives again fails below
    t_end = time.monotonic() + 3.0
    while rig.last("odom").twist.twist.linear.x <= 0.1 and time.monotonic() < t_end:
        rig.drive([1.0, 0.0, 0.0], 0.2)
    t_moving = time.monotonic()
    rig.drive([1.0, 0.0, 0.0], 1.0, zero_first=False)    # moving: no zero to brake it
    after = [s for s in g["odom"] if s[0] > t_moving + 0.3]
    # the median: a starved moment at the end of the drive may still brake the wheels briefly
    assert after and float(np.median([m.twist.twist.linear.x for _, m in after])) == pytest.approx(
        1.0 * WHEEL_RADIUS, rel=0.15), [m.twist.twist.linear.x for _, m in after]
    rig.spin(0.6)                                        # the bridge's timeout: stopped again


def test_bad_parameters_end_the_twin_with_one_line(ros, tmp_path):
    """A slope outside the config's range, an unreadable machine parameter file: exit 2, one
    line naming the parameter and what is expected."""
    procs = {
        "slopes": RosProcess("lhd_sim_node.twin_node", {"link": str(tmp_path / "a"), "slopes_deg": "20,40"},
                             tmp_path / "slopes.log"),
        "machine": RosProcess("lhd_sim_node.twin_node", {"link": str(tmp_path / "b"),
                                                         "machine_params": str(tmp_path / "missing.yaml")},
                              tmp_path / "machine.log"),
    }
    for p in procs.values():
        p.proc.wait(timeout=30.0)
    logs = {k: p.log() for k, p in procs.items()}
    assert [p.stop() for p in procs.values()] == [2, 2], logs
    assert "parameter 'slopes_deg'" in logs["slopes"] and "[40.0] outside the config's range [15, 30]" in logs["slopes"]
    assert "parameter 'machine_params'" in logs["machine"] and "expected a file like config/real_machine.yaml" \
        in logs["machine"]
    assert "Traceback" not in logs["slopes"] + logs["machine"]
    assert not os.path.exists(tmp_path / "a") and not os.path.exists(tmp_path / "b")


def test_device_watchdog_stops_the_machine_when_the_bridge_dies(rig):
    """The bridge is killed (SIGKILL: no stop frame on the way out) while the machine drives: the
    device's own watchdog stops it 250 ms after the last command frame."""
    g = rig.got
    rig.drive([1.0, 0.0, 0.0], 1.0)
    t_end = time.monotonic() + 3.0          # a loaded machine may still be accelerating it
    while rig.last("odom").twist.twist.linear.x <= 0.1 and time.monotonic() < t_end:
        rig.drive([1.0, 0.0, 0.0], 0.2)
    assert rig.last("odom").twist.twist.linear.x > 0.1
    trips = int(rig.twin_status("device")["watchdog_trips"])    # a starved bridge may have tripped it before
    rt0 = rig.twin_status("real time")
    os.killpg(rig.bridge.proc.pid, signal.SIGKILL)
    t_kill = time.time()            # the twin stamps its states on the system clock

    for _ in range(20):                                 # the commands go nowhere now
        rig.pub_cmd.publish(Float64MultiArray(data=[1.0, 0.0, 0.0]))
        rig.spin(0.05)
    # judged by the instant each state is of (its stamp), not by when this process heard it: a
    # starved test process hears a backlog of earlier, still moving states late. The machine
    # stops 250 ms after the last frame; stopped short, it rocks on its tyres (a few cm/s for
    # about half a second), then rests
    assert spin_until(rig.node, lambda: any(_stamp(m) > t_kill + 2.0 for _, m in g["odom"]), 10.0), rig.twin.log()
    after = [(_stamp(m) - t_kill, m.twist.twist.linear.x) for _, m in g["odom"] if _stamp(m) > t_kill]
    profile = [(round(t, 3), round(v, 4)) for t, v in after] + [rig.twin_status("device"), rig.twin_status("real time")]
    first_stop = next((t for t, v in after if abs(v) < 0.02), math.inf)
    assert first_stop < 0.25 + 0.4, profile
    rest = [v for t, v in after if t > 1.5]
    assert rest and all(abs(v) < 0.005 for v in rest), profile
    assert spin_until(rig.node, lambda: int(rig.twin_status("device")["watchdog_trips"]) == trips + 1, timeout=3.0), \
        rig.twin_status("device")
    dev = rig.twin_status("device")
    assert dev["watchdog_holds"] == "True" and "watchdog" in dev["message"]
    # the device kept real time with its bridge dead: the factor over the whole time since the kill, from the
    # twin's own clock readings at two of its reports (the wall time since its loop began = lag + simulated
    # time). One report's factor covers one diagnostics period (0.25 s here, 12.5 chunks of 20 ms): a chunk
    # or two of phase moves it by 8-16 % with no chunk late (CI measured 0.85 at level OK)
    rt = rig.twin_status("real time")
    sim0, sim1 = float(rt0["sim_time_s"]), float(rt["sim_time_s"])
    wall0, wall1 = float(rt0["lag_s"]) + sim0, float(rt["lag_s"]) + sim1
    assert wall1 - wall0 > 1.5, (rt0, rt)
    print(f"\nreal-time factor since the kill: {(sim1 - sim0) / (wall1 - wall0):.4f} over {wall1 - wall0:.2f} s")
    assert 0.9 < (sim1 - sim0) / (wall1 - wall0) < 1.1, (rt0, rt)
