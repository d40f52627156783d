"""The policy node's trigger:=odom over DDS: a decision per fresh /lhd/odom, at most rate_hz (an
odometry sooner than 1/rate_hz - odom_margin after the last decision decides nothing), each naming
the odometry stamp it used; when the odometry stops, the steady fallback keeps deciding at about
rate_hz and its commands become the zero command once the odometry is older than input_timeout."""
import math
import time

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from nav_msgs.msg import Odometry
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64, Float64MultiArray

from rosutil import RosProcess, init_ros, shutdown_ros, spin_until

REL = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
ODOM_HZ = 30.0           # a 30 fps camera's odometry
RATE_HZ = 10.0
MARGIN = 0.01            # s, the node's default odom_margin
INPUT_TIMEOUT = 0.5


@pytest.fixture(scope="module")
def ros():
    init_ros()
    node = rclpy.create_node("test_policy_trigger_odom")
    yield node
    node.destroy_node()
    shutdown_ros()


def test_decides_on_fresh_odometry_at_most_rate_hz_then_falls_back_to_zero(ros, tmp_path):
    proc = RosProcess("lhd_loading_ros.nodes.policy_node", {"trigger": "odom", "rate_hz": RATE_HZ,
                                                            "input_timeout": INPUT_TIMEOUT}, tmp_path / "policy.log")
    js = JointState(name=["boom", "bucket"], position=[0.0, 0.0], velocity=[0.0, 0.0])
    od = Odometry()
    od.pose.pose.position.x, od.pose.pose.position.z, od.pose.pose.orientation.w = 0.10 - 1.711, 0.137, 1.0
    od.twist.twist.linear.x = 0.35
    p_js = ros.create_publisher(JointState, "/lhd/joint_states", qos_profile_sensor_data)
    p_od = ros.create_publisher(Odometry, "/lhd/odom", qos_profile_sensor_data)
    p_dr = [ros.create_publisher(Bool, f"/lhd/wheel_drift/{w}", qos_profile_sensor_data) for w in ("front", "rear")]
    p_sl = ros.create_publisher(Float64, "/lhd/pile/slope", LATCHED)
    p_ez = ros.create_publisher(Float64MultiArray, "/lhd/pile/end_zone", LATCHED)
    p_st = ros.create_publisher(DiagnosticStatus, "/lhd/episode", LATCHED)
    p_sl.publish(Float64(data=math.radians(20.0)))
    p_ez.publish(Float64MultiArray(data=[0.52, 0.85, 0.35]))
    running = DiagnosticStatus(name="t", message="running", values=[KeyValue(key="state", value="running"),
                                                                     KeyValue(key="episode", value="1")])
    p_st.publish(running)
    sent = set()                          # odometry stamps published (ns)
    odom_on = {"v": True}
    decisions, cmds = [], []

    def tick():
        p_st.publish(running)             # repeated, as the supervisor does (status_timeout)
        p_js.publish(js)
        for p in p_dr:
            p.publish(Bool(data=False))
        if odom_on["v"]:
            od.header.stamp = ros.get_clock().now().to_msg()
            sent.add(od.header.stamp.sec * 1_000_000_000 + od.header.stamp.nanosec)
            p_od.publish(od)

    def on_dec(m):
        kv = {k.key: k.value for k in m.values}
        decisions.append((time.monotonic(), m.message, int(kv["odom_stamp_ns"]), int(kv["decided_mono_ns"]),
                          [float(v) for v in kv["command"].split(",")], kv["reason"]))

    timer = ros.create_timer(1.0 / ODOM_HZ, tick)
    ros.create_subscription(DiagnosticStatus, "/lhd/policy/decision", on_dec, REL)
    ros.create_subscription(Float64MultiArray, "/lhd/cmd", lambda m: cmds.append(list(m.data)), REL)
    try:
        assert spin_until(ros, lambda: sum(1 for d in decisions if d[1] == "odom" and not d[5]) >= 5, 60.0), \
            proc.log()[-3000:]
        t0 = time.monotonic()
        spin_until(ros, lambda: False, 3.0)
        window = [d for d in decisions if d[0] >= t0]
        odom = [d for d in window if d[1] == "odom"]
        assert len(odom) >= 0.5 * 3.0 * RATE_HZ, window          # most decisions come from the odometry
        for d in odom:
            assert d[2] in sent                                   # the stamp of an odometry this test sent
        mono = [d[3] * 1e-9 for d in window]
        gaps = [b - a for a, b in zip(mono, mono[1:])]
        # at most rate_hz: never two decisions closer than 1/rate_hz - margin on the node's own
        # decision clock (decided_mono_ns; the commands' publication times, mono_ns, jitter by the
        # cycle's work on a loaded machine). The fallback after a fallback waits a period less
        # half a check period (1/rate_hz - 12.5 ms), the tightest rule of the two
        assert min(gaps) >= 1.0 / RATE_HZ - 0.5 / RATE_HZ / 4 - 1e-6, gaps
        # 30 Hz odometry, 10 Hz decisions: most odometry messages decide nothing
        assert len(window) <= 3.0 * RATE_HZ + 2
        # the odometry stops: the fallback decides from the latest inputs, then zero commands
        odom_on["v"] = False
        t_stop = time.monotonic()
        spin_until(ros, lambda: False, 2.0)
        after = [d for d in decisions if d[0] >= t_stop + 0.2]
        assert after and all(d[1] == "fallback" for d in after), after
        # steady at about rate_hz (the fallback's own period); a loaded machine may stretch it
        fb = [d[3] * 1e-9 for d in after]
        mean_gap = (fb[-1] - fb[0]) / (len(fb) - 1)
        assert 0.9 / RATE_HZ <= mean_gap <= 1.6 / RATE_HZ, mean_gap
        late = [d for d in after if d[0] >= t_stop + INPUT_TIMEOUT + 0.3]
        assert late and all(d[4] == [0.0, 0.0, 0.0] and "odom" in d[5] for d in late), late
    finally:
        ros.destroy_timer(timer)
        proc.stop()
