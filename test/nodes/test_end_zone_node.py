"""The end-zone node as a real process over DDS (issue 15 §1), fed by the LiDAR slope node (also a
process) with synthetic LaserScans of a pile: the latched end zone and zones against the closed-form
wedge written here; the republish threshold (jitter and small moves do not republish, a real move
does; a lower threshold at run time releases the pending estimate); stale input; bad slope_stamped
samples publish nothing and say why; runtime density; the surveyed file in its forms (one under a
namespace) and bad surveyed files ending the node with exit 2 and one line."""
import math
import time

import numpy as np
import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import Vector3Stamped
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import LaserScan
from std_msgs.msg import Float64MultiArray

from lhd_loading_ros.perception.synthetic import synthetic_scan

from rosutil import RosProcess, init_ros, shutdown_ros, spin_until

NODE, LIDAR = "lhd_loading_ros.nodes.end_zone_node", "lhd_loading_ros.nodes.lidar_slope_node"
OK, WARN, ERROR = DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
REL = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
# the paper's pile and end zone (config/lhd_params.yaml), written out for the closed form
H, W, M_MIN, M_MAX, Z_MIN, D_CUTOFF = 0.68, 0.4, 65.0, 170.0, 0.35, 0.1
RHO_MIN, RHO_MAX = 1760.0, 2000.0    # pile.density_min/max (gravel)
RHO = (RHO_MIN + RHO_MAX) / 2        # midpoint: the node's default density
# the observation zone's far edge, derived from the pile (task.normalisers_from_pile, docs/modeling.md):
# the end zone's far edge on the shallowest (15 deg), lightest pile, plus the paper's 0.03 m of room
X_INIT_OBS, Y_OBS, Z_OBS = 0.1, 0.4, 0.4
X_OBS = X_INIT_OBS + math.sqrt(2 * M_MAX / (RHO_MIN * W * math.tan(math.radians(15.0)))) + 0.03
FIT_DEG, FIT_TOE = 1.0, 0.03         # the LiDAR node's fit error on these scans (test_lidar_ros.py)
THRESHOLD = 0.02                     # the node's default republish_threshold, m


def wedge_zones(alpha, toe, rho=RHO):
    """Closed form: the intact wedge rising at alpha from the toe holds rho W tan(alpha) s^2 / 2
    between the toe and toe + s; the end zone spans the s holding M_MIN and M_MAX; the restricted
    cut is D_CUTOFF before the back end toe + H / tan(alpha); the observation zone starts
    X_INIT_OBS before the toe."""
    s = [math.sqrt(2 * m / (rho * W * math.tan(alpha))) for m in (M_MIN, M_MAX)]
    return [toe + s[0], toe + s[1], Z_MIN, toe + H / math.tan(alpha) - D_CUTOFF, toe - X_INIT_OBS,
            toe - X_INIT_OBS + X_OBS, Y_OBS / 2, Z_OBS]


def tracked_change(a, b):
    """Largest move of x_min, x_max, x_cutoff (the limits the node's threshold watches)."""
    return max(abs(a[i] - b[i]) for i in (0, 1, 3))


@pytest.fixture(scope="module")
def ros():
    init_ros()
    node = rclpy.create_node("test_end_zone")
    yield node
    node.destroy_node()
    shutdown_ros()


def scan_msg(alpha_deg, toe_x, seed, t):
    r, amin, inc, _ = synthetic_scan(math.radians(alpha_deg), np.random.default_rng(seed), toe_x=toe_x)
    m = LaserScan()
    m.header.frame_id = "lidar"
    m.header.stamp.sec, m.header.stamp.nanosec = int(t), int(round((t % 1) * 1e9))
    m.angle_min, m.angle_increment = float(amin), float(inc)
    m.angle_max = float(amin + inc * (len(r) - 1))
    m.range_min, m.range_max = 0.05, 30.0
    m.ranges = [float(v) for v in r]
    return m


class Diag:
    def __init__(self, node, name):
        self.name, self.seen = name, []
        self.sub = node.create_subscription(DiagnosticArray, "/diagnostics", self._on, 50)

    def _on(self, msg):
        self.seen += [st for st in msg.status if st.name == self.name]

    def wait(self, node, level, text, timeout=10.0):
        start = len(self.seen)
        ok = spin_until(node, lambda: any(st.level == level and text in st.message for st in self.seen[start:]),
                        timeout)
        return ok, [(st.level, st.message) for st in self.seen[start:]][-3:]

    def values(self):
        return {kv.key: kv.value for kv in self.seen[-1].values}


def late_zones(name, ns="/lhd", timeout=10.0):
    """end_zone and zones on a latched subscription made now, by a new node."""
    node = rclpy.create_node(name)
    got = {}
    node.create_subscription(Float64MultiArray, f"{ns}/pile/end_zone", lambda m: got.setdefault("end", list(m.data)),
                             LATCHED)
    node.create_subscription(Float64MultiArray, f"{ns}/pile/zones", lambda m: got.setdefault("zones", list(m.data)),
                             LATCHED)
    try:
        spin_until(node, lambda: len(got) == 2, timeout)
        return got
    finally:
        node.destroy_node()


def set_param(ros, target, name, value):
    client = AsyncParameterClient(ros, target)
    assert client.wait_for_services(20.0)
    fut = client.set_parameters([Parameter(name, value=value)])
    assert spin_until(ros, fut.done, 20.0)
    return fut.result().results[0]


def test_lidar_pile_to_latched_zones_threshold_stale_and_bad_input(ros, tmp_path):
    # each scan's own fit (filter_window 1): the scenario moves the pile scan by scan
    lidar = RosProcess(LIDAR, {"filter_window": 1}, tmp_path / "lidar.log")
    ez = RosProcess(NODE, {"stale_warn_s": 2.0}, tmp_path / "end_zone.log")
    fits, published = [], []
    subs = [ros.create_subscription(Vector3Stamped, "/lhd/pile/slope_stamped", fits.append, REL),
            ros.create_subscription(Float64MultiArray, "/lhd/pile/zones", lambda m: published.append(list(m.data)),
                                    REL)]
    diag = Diag(ros, "/end_zone_node: zones")
    pub_scan = ros.create_publisher(LaserScan, "/lidar/scan", qos_profile_sensor_data)
    # volatile, as a user's `ros2 topic pub`: the node's latched subscription does not match it (by
    # design, the other one takes it): no warning for that
    pub_slope = ros.create_publisher(Vector3Stamped, "/lhd/pile/slope_stamped", REL,
                                     event_callbacks=PublisherEventCallbacks(incompatible_qos=lambda _: None))
    t = [100.0]

    def scan(alpha_deg, toe_x, seed, republish):
        """One scan; the LiDAR's fit; whether the end-zone node published (waits for it, or 1.5 s).
        The scan goes best effort (sensor QoS), as a LiDAR driver's: one the network lost is sent
        again; the fit is the one carrying this scan's stamp."""
        n_pub = len(published)
        t[0] += 0.5
        msg = scan_msg(alpha_deg, toe_x, seed, t[0])
        mine = []

        def fitted():
            mine[:] = [f for f in fits if (f.header.stamp.sec, f.header.stamp.nanosec) ==
                       (msg.header.stamp.sec, msg.header.stamp.nanosec)]
            return bool(mine)

        for _ in range(5):
            pub_scan.publish(msg)
            if spin_until(ros, fitted, 2.0):
                break
        assert mine, lidar.log()
        f = mine[0]
        spin_until(ros, lambda: len(published) > n_pub, 10.0 if republish else 1.5)
        return f.vector, len(published) > n_pub

    try:
        # matched from this side too (the graph can list the node before the writer has matched it)
        assert spin_until(ros, lambda: pub_scan.get_subscription_count() > 0 and
                          ros.count_subscribers("/lhd/pile/slope_stamped") >= 3 and
                          ros.count_publishers("/lhd/pile/zones") > 0, 30.0), (lidar.log(), ez.log())
        ok, seen = diag.wait(ros, WARN, "no slope yet on /lhd/pile/slope_stamped")
        assert ok, seen

        # a 20 deg pile whose toe is 0.05 m into the pile frame
        v, pub = scan(20.0, 0.05, seed=1, republish=True)
        assert pub, ez.log()
        first = published[-1]
        # the node's computation: the closed form at the LiDAR's own fit ...
        assert first == pytest.approx(wedge_zones(v.x, v.y), abs=1e-9)
        # ... and within the fit error of the true pile's (every corner of +-1 deg, +-0.03 m)
        corners = [wedge_zones(math.radians(20.0 + da), 0.05 + dt) for da in (-FIT_DEG, FIT_DEG)
                   for dt in (-FIT_TOE, FIT_TOE)]
        for i in range(8):
            lo, hi = min(c[i] for c in corners), max(c[i] for c in corners)
            assert lo - 1e-9 <= first[i] <= hi + 1e-9, (i, first[i], lo, hi)
        true = wedge_zones(math.radians(20.0), 0.05)
        assert abs(first[0] - true[0]) < 0.02 and abs(first[1] - true[1]) < 0.02     # what this fit achieved
        # a late subscriber gets both, latched, with the same values
        got = late_zones("late_policy")
        assert got["zones"] == first and got["end"] == first[:3], got
        ok, seen = diag.wait(ros, OK, "end zone x")
        assert ok and f"slope {math.degrees(v.x):.1f} deg, toe {v.y:.3f} m, {RHO:.0f} kg/m^3" in seen[-1][1], seen

        # below the threshold: the same pile scanned again (range noise), the toe moved 8 mm
        for alpha, toe, seed in ((20.0, 0.05, 2), (20.0, 0.058, 3)):
            v, pub = scan(alpha, toe, seed, republish=False)
            change = tracked_change(wedge_zones(v.x, v.y), first)
            assert change < THRESHOLD - 0.005, change       # the scenario really is below
            assert not pub, (alpha, toe, change)
        pending = wedge_zones(v.x, v.y)
        # a lower threshold at run time publishes the pending estimate
        n = len(published)
        assert set_param(ros, "/end_zone_node", "republish_threshold", 0.001).successful
        assert spin_until(ros, lambda: len(published) > n, 10.0)
        assert published[-1] == pytest.approx(pending, abs=1e-9)
        assert set_param(ros, "/end_zone_node", "republish_threshold", THRESHOLD).successful
        # above: the toe 0.06 m farther, then a 24 deg face
        for alpha, toe, seed in ((20.0, 0.118, 4), (24.0, 0.118, 5)):
            before = published[-1]
            v, pub = scan(alpha, toe, seed, republish=True)
            assert tracked_change(wedge_zones(v.x, v.y), before) > THRESHOLD + 0.01
            assert pub and published[-1] == pytest.approx(wedge_zones(v.x, v.y), abs=1e-9)
        good = published[-1]
        good_fit = (v.x, v.y)

        # no slope for stale_warn_s (2 s): WARN, the latched zones keep their meaning
        ok, seen = diag.wait(ros, WARN, "no slope for", timeout=8.0)
        assert ok and "keeps its meaning" in seen[-1][1], seen

        # bad samples (from a volatile publisher): nothing published, ERROR naming the value
        n = len(published)
        for alpha, toe, res, text, frame in (
                (math.nan, 0.0, 0.01, "slope (x) = nan not finite", ""),
                (math.radians(60.0), 0.0, 0.01, "slope 60.00 deg outside the physical range", ""),
                (math.radians(20.0), 7.0, 0.01, "toe x 7.000 m: expected |toe x| <= 5 m", ""),
                (math.radians(20.0), 0.0, math.inf, "residual (z) = inf not finite", ""),
                (math.radians(20.0), 0.0, -1.0, "residual (z) -1 m: expected the fit's RMS residual, >= 0 m", ""),
                (math.radians(20.0), 0.3, 0.01, "frame_id 'lidar'; expected the toe in the pile frame 'pile'", "lidar")):
            for _ in range(5):        # five in half a second: one log line (throttled)
                m = Vector3Stamped()
                m.header.frame_id = frame
                m.vector.x, m.vector.y, m.vector.z = alpha, toe, res
                pub_slope.publish(m)
                spin_until(ros, lambda: False, 0.1)
            ok, seen = diag.wait(ros, ERROR, text)
            assert ok and "the last good zones stay latched" in seen[-1][1], seen
        spin_until(ros, lambda: False, 0.5)
        assert len(published) == n
        assert all(math.isfinite(x) for z in published for x in z)
        got = late_zones("late_after_bad")
        assert got["zones"] == good, got
        assert 1 <= ez.log().count("no end zone published: /lhd/pile/slope_stamped: slope (x) = nan") <= 2, ez.log()
        # every sample counted once: the LiDAR's latched ones reach both subscriptions of the node
        # (the copy is dropped), the test's volatile ones one; this test hears them all once too
        spin_until(ros, lambda: False, 1.2)
        assert (int(diag.values()["rejected"]), int(diag.values()["received"])) == (30, len(fits)), diag.values()

        # runtime density: the zones of the last good pile with 1600 kg/m^3 (lighter: further out), published at once;
        # a density in t/m^3 is refused with the reason
        res = set_param(ros, "/end_zone_node", "density", 3.2)
        assert not res.successful and "outside [500, 6000] kg/m^3" in res.reason, res.reason
        n = len(published)
        assert set_param(ros, "/end_zone_node", "density", 1600.0).successful
        assert spin_until(ros, lambda: len(published) > n, 10.0)
        assert published[-1] == pytest.approx(wedge_zones(*good_fit, rho=1600.0), abs=1e-9)
        assert published[-1][1] > good[1]
    finally:
        for s in subs:
            ros.destroy_subscription(s)
        ros.destroy_subscription(diag.sub)
        ros.destroy_publisher(pub_scan)
        ros.destroy_publisher(pub_slope)
        rc_ez, rc_lidar = ez.stop(), lidar.stop()
    assert rc_ez == 0 and rc_lidar == 0, (ez.log(), lidar.log())


def test_surveyed_files_and_bad_ones(ros, tmp_path):
    pile = tmp_path / "pile.yaml"
    pile.write_text("slope_deg: 25.0\ntoe_x: -0.04\ndensity: 3000\n")
    end = tmp_path / "end.yaml"
    end.write_text("end_zone: [0.5, 0.8, 0.35]\nx_cutoff: 1.4\n")
    bad = {"unknown": ("slope_deg: 25\ntoe_x: 0\nslop: 3\n", "unknown key 'slop'"),
           "steep": ("slope_deg: 65\ntoe_x: 0\n", "slope 65.00 deg outside the physical range [5, 50] deg"),
           "light": ("slope_deg: 45\ntoe_x: 0\ndensity: 600\n", "holds 55 kg, less than m_max = 170 kg")}
    procs = [RosProcess(NODE, {"source": "surveyed", "surveyed_file": str(pile)}, tmp_path / "pile.log"),
             RosProcess(NODE, {"source": "surveyed", "surveyed_file": str(end)}, tmp_path / "end.log",
                        remaps={"__ns": "/lhd2"})]
    bad_procs = {}
    for name, (text, _) in bad.items():
        (tmp_path / f"{name}.yaml").write_text(text)
        bad_procs[name] = RosProcess(NODE, {"source": "surveyed", "surveyed_file": str(tmp_path / f"{name}.yaml")},
                                     tmp_path / f"bad_{name}.log")
    bad_procs["missing"] = RosProcess(NODE, {"source": "surveyed", "surveyed_file": str(tmp_path / "none.yaml")},
                                      tmp_path / "bad_missing.log")
    bad_procs["no_source"] = RosProcess(NODE, {"surveyed_file": str(pile)}, tmp_path / "bad_no_source.log")
    bad["missing"] = (None, "none.yaml: cannot read it")
    bad["no_source"] = (None, "is set but source is lidar")
    diag = Diag(ros, "/end_zone_node: zones")
    try:
        t_end = time.monotonic() + 60.0
        while time.monotonic() < t_end and not all("end zone x" in p.log() for p in procs):
            time.sleep(0.1)
        # subscribed after both published: latched
        got = late_zones("late_pile")
        # the surveyed pile with its own density: 25 deg, toe 0.04 m before {M}'s origin, 3000 kg/m^3
        assert got["zones"] == pytest.approx(wedge_zones(math.radians(25.0), -0.04, rho=3000.0), abs=1e-9), got
        assert got["end"] == got["zones"][:3]
        got2 = late_zones("late_end", ns="/lhd2")
        # the end zone alone: the paper's observation zone about the toe, the cut as surveyed
        assert got2["zones"] == pytest.approx([0.5, 0.8, 0.35, 1.4, -X_INIT_OBS, X_OBS - X_INIT_OBS, Y_OBS / 2,
                                               Z_OBS]), got2
        assert got2["end"] == pytest.approx([0.5, 0.8, 0.35])
        ok, seen = diag.wait(ros, OK, "surveyed slope 25.0 deg, toe -0.040 m, 3000 kg/m^3")
        assert ok, seen
        for name, p in bad_procs.items():
            assert p.proc.wait(60) == 2, (name, p.log())
            p.stop()
            log = p.log()
            assert bad[name][1] in log and log.startswith("end_zone_node: ") and "Traceback" not in log, (name, log)
            assert len(log.strip().splitlines()) == 1, (name, log)
    finally:
        ros.destroy_subscription(diag.sub)
        rcs = [p.stop() for p in procs]
    assert rcs == [0, 0], [p.log() for p in procs]
