"""The supervisor's /lhd/supervisor/markers over DDS (a real supervisor process, fed at 50 Hz by
this test): the zone boxes at the coordinates of /lhd/pile/zones, latched (a subscriber that
joins late gets the picture), the tip trajectory growing while the machine drives during an
attempt, kept after the end, and cleared (DELETEALL first, no trajectory) when the next attempt
is armed."""
import math
import threading
import time

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from nav_msgs.msg import Odometry
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64, Float64MultiArray
from std_srvs.srv import Trigger
from visualization_msgs.msg import Marker, MarkerArray

from rosutil import RosProcess, init_ros, shutdown_ros

REL = QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
R_WHEEL = 0.137
REACH = math.sqrt(0.55 ** 2 - 0.30 ** 2)
TIP_AHEAD = 0.80 + 0.15 + REACH + 0.30             # tip ahead of the rear axle in the attack pose (config)
ZONES = [0.5, 1.0, 0.35, 1.5, -0.1, 1.1, 0.2, 0.4]  # x_min, x_max, z_min, x_cutoff, x_obs_start, x_obs_end, y_half, z_top


def wait_for(pred, timeout, step=0.01):
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        if pred():
            return True
        time.sleep(step)
    return pred()


class Feeder:
    def __init__(self, node):
        self.node = node
        self.base_x, self.boom, self.bucket = -TIP_AHEAD, 0.0, 0.0
        self.slope = None                    # rad; once set, published at every tick, as the LiDAR node does per scan
        self.arrays = []                     # (arrival, MarkerArray)
        self.states = []
        self.lock = threading.Lock()
        self.pub_js = node.create_publisher(JointState, "/lhd/joint_states", REL)
        self.pub_odom = node.create_publisher(Odometry, "/lhd/odom", REL)
        self.pub_front = node.create_publisher(Bool, "/lhd/wheel_drift/front", REL)
        self.pub_rear = node.create_publisher(Bool, "/lhd/wheel_drift/rear", REL)
        self.pub_hw = node.create_publisher(DiagnosticStatus, "/lhd/hw/status", REL)
        self.pub_slope = node.create_publisher(Float64, "/lhd/pile/slope", LATCHED)
        self.pub_zones = node.create_publisher(Float64MultiArray, "/lhd/pile/zones", LATCHED)
        node.create_subscription(MarkerArray, "/lhd/supervisor/markers", self._on_markers, LATCHED)
        node.create_subscription(DiagnosticStatus, "/lhd/episode", self._on_status,
                                 QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                                            history=HistoryPolicy.KEEP_LAST,
                                            durability=DurabilityPolicy.TRANSIENT_LOCAL))
        self.arm_client = node.create_client(Trigger, "/lhd/arm")
        node.create_timer(0.02, self._tick)
        self.executor = SingleThreadedExecutor(context=node.context)
        self.executor.add_node(node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def _on_markers(self, msg):
        with self.lock:
            self.arrays.append((time.monotonic(), msg))

    def _on_status(self, msg):
        self.states.append({k.key: k.value for k in msg.values})

    def _tick(self):
        stamp = self.node.get_clock().now().to_msg()
        o = Odometry()
        o.header.stamp = stamp
        o.pose.pose.position.x, o.pose.pose.position.z = self.base_x, R_WHEEL
        o.pose.pose.orientation.w = 1.0
        self.pub_odom.publish(o)
        js = JointState()
        js.header.stamp = stamp
        js.name = ["boom", "bucket"]
        js.position = [self.boom, self.bucket]
        js.velocity = [0.0, 0.0]
        self.pub_js.publish(js)
        self.pub_front.publish(Bool(data=False))
        self.pub_rear.publish(Bool(data=False))
        st = DiagnosticStatus(level=DiagnosticStatus.OK, name="/lhd_bridge: device", message="drive enabled")
        st.values = [KeyValue(key="estop", value="False")]
        self.pub_hw.publish(st)
        if self.slope is not None:
            self.pub_slope.publish(Float64(data=self.slope))

    def arm(self):
        assert self.arm_client.wait_for_service(timeout_sec=30.0), "no supervisor"
        fut = self.arm_client.call_async(Trigger.Request())
        assert wait_for(fut.done, 10.0)
        assert fut.result().success, fut.result().message

    def since(self, t):
        with self.lock:
            return [m for at, m in self.arrays if at >= t]

    def state(self):
        return self.states[-1] if self.states else {}


def parts(arr):
    return {(m.ns, m.id): m for m in arr.markers}


def tip_points(arr):
    m = parts(arr).get(("tip", 0))
    return [] if m is None or m.action != Marker.ADD else [(p.x, p.z) for p in m.points]


@pytest.fixture(scope="module")
def feeder(tmp_path_factory):
    init_ros()
    node = rclpy.create_node("test_supervisor_markers")
    f = Feeder(node)
    run = tmp_path_factory.mktemp("run")
    f.proc = RosProcess("lhd_loading_ros.nodes.supervisor_node",
                        {"run_dir": str(run), "attempt_timeout": 30.0, "arm_delay": 0.0, "markers_hz": 20.0},
                        run.parent / "supervisor_markers.log")
    yield f
    f.proc.stop()
    f.executor.shutdown()
    f.thread.join(5.0)
    node.destroy_node()
    shutdown_ros()


def test_zones_trajectory_and_clearing(feeder):
    f = feeder
    # the slope as the LiDAR node gives it, every scan (a single latched sample was lost once in CI
    # to a discovery race, leaving the supervisor without a slope at arming)
    f.slope = math.radians(20.0)
    f.pub_slope.publish(Float64(data=f.slope))
    f.pub_zones.publish(Float64MultiArray(data=ZONES))

    def zones_shown():
        return f.arrays and ("zones", 0) in parts(f.arrays[-1][1]) and \
            parts(f.arrays[-1][1])[("zones", 0)].action == Marker.ADD
    assert wait_for(zones_shown, 40.0), f.proc.log()
    p = parts(f.arrays[-1][1])
    end, permitted, cutoff = p[("zones", 0)], p[("zones", 1)], p[("zones", 2)]
    assert end.header.frame_id == "pile" and end.type == Marker.CUBE and end.text == "end"
    # end: x_min..x_max, |y| <= y_half, z_min..z_min + 0.4
    assert (end.pose.position.x, end.pose.position.z, end.scale.x, end.scale.y, end.scale.z) == \
        pytest.approx((0.75, 0.55, 0.5, 0.4, 0.4))
    # permitted: x_obs_start..min(x_obs_end, x_cutoff), floor..z_top; cutoff: a wall at x_cutoff
    assert (permitted.pose.position.x, permitted.scale.x, permitted.scale.z) == pytest.approx((0.5, 1.2, 0.4))
    assert cutoff.pose.position.x == pytest.approx(1.5)

    # attempt 1: the base drives 0.25 m forward in 1 s; the trajectory grows
    t0 = time.monotonic()
    f.arm()
    time.sleep(0.1)     # the trajectory's first point is the attack pose (not a race with the first move)
    for k in range(1, 26):
        f.base_x = -TIP_AHEAD + 0.01 * k
        time.sleep(0.04)
    assert wait_for(lambda: (tip_points(f.arrays[-1][1]) or [(0, 0)])[-1][0] > 0.249, 3.0)
    seen = [len(tip_points(a)) for a in f.since(t0)]
    # grew in steps: one point per 1 cm move the supervisor saw (25 moves in 1 s; on a loaded CI
    # machine a stall of the feeder or the node merges moves, 21 of 25 seen once: hence >= 10)
    assert seen[-1] >= 10 and sorted(seen) == seen and len(set(seen)) >= 3, seen
    pts = tip_points(f.arrays[-1][1])
    gaps = [math.dist(a, b) for a, b in zip(pts, pts[1:])]
    assert min(gaps) >= 0.005 - 1e-6 and max(gaps) <= 0.1, gaps        # TipTrail's 5 mm spacing, no jump
    assert pts[0] == pytest.approx((0.0, 0.015), abs=2e-3) and pts[-1] == pytest.approx((0.25, 0.015), abs=2e-3)
    assert f.state().get("state") == "running"

    # a late viewer: the latched array carries zones and the trajectory
    late = []
    sub = f.node.create_subscription(MarkerArray, "/lhd/supervisor/markers", late.append, LATCHED)
    assert wait_for(lambda: late, 5.0)
    assert ("zones", 0) in parts(late[-1]) and len(tip_points(late[-1])) >= 24
    # (left in place: destroying it while the feeder's executor thread waits on the node killed that thread, rclpy's
    # InvalidHandle "destruction was requested", and with it every input the supervisor judges by; CI 2026-12-01)
    del sub

    # the end (success: tip lifted into the end zone) keeps the trajectory; the next arming clears it
    f.boom, f.bucket = -0.5, 0.3
    f.base_x = 0.7 - (0.95 + REACH * math.cos(-0.5) - 0.30 * math.sin(-0.5)
                      + 0.30 * math.cos(-0.8) - 0.105 * math.sin(-0.8))
    assert wait_for(lambda: f.state().get("state") == "success", 5.0), f.state()
    time.sleep(0.2)
    n_end = len(tip_points(f.arrays[-1][1]))
    assert n_end > 24
    f.boom, f.bucket, f.base_x = 0.0, 0.0, -TIP_AHEAD
    time.sleep(0.3)
    assert len(tip_points(f.arrays[-1][1])) == n_end          # not live: nothing added
    t1 = time.monotonic()
    f.arm()
    assert wait_for(lambda: f.since(t1), 3.0)
    first = f.since(t1)[0]
    assert first.markers[0].action == Marker.DELETEALL
    assert parts(first)[("tip", 0)].action == Marker.DELETE and parts(first)[("zones", 0)].action == Marker.ADD
    for k in range(1, 11):
        f.base_x = -TIP_AHEAD + 0.01 * k
        time.sleep(0.04)
    assert wait_for(lambda: len(tip_points(f.arrays[-1][1])) >= 8, 3.0)
    assert all(m.action != Marker.DELETEALL for a in f.since(t1)[1:] for m in a.markers)
