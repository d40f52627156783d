"""The bridge node as a real process, over real DDS, against the device emulator on a real
pseudo-terminal: round trip, safety, watchdog timing, unplug / re-plug."""
import math
import time

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64MultiArray

from lhd_hw_bridge.fake_due import FakeDue
from lhd_hw_bridge.protocol import CommandFrame

from rosutil import RosProcess, init_ros, shutdown_ros, spin_until


@pytest.fixture(scope="module")
def ros():
    init_ros()
    yield
    shutdown_ros()


@pytest.fixture
def rig(ros, tmp_path):
    link = str(tmp_path / "due")
    dev = FakeDue(link=link, rate=100.0, watchdog=0.25)
    dev.start()
    bridge = RosProcess("lhd_hw_bridge.bridge_node", {"port": link}, tmp_path / "bridge.log")
    node = rclpy.create_node("bridge_test")
    got = {"js": [], "drift": [], "front": [], "rear": [], "diag": []}
    node.create_subscription(JointState, "/lhd/joint_states", lambda m: got["js"].append(m), 50)
    node.create_subscription(Bool, "/lhd/wheel_drift", lambda m: got["drift"].append(m.data), 50)
    node.create_subscription(Bool, "/lhd/wheel_drift/front", lambda m: got["front"].append(m.data), 50)
    node.create_subscription(Bool, "/lhd/wheel_drift/rear", lambda m: got["rear"].append(m.data), 50)
    node.create_subscription(DiagnosticArray, "/diagnostics", lambda m: got["diag"].append(m), 10)
    pub = node.create_publisher(Float64MultiArray, "/lhd/cmd", 1)
    ok = spin_until(node, lambda: len(got["js"]) > 5, timeout=20.0)
    assert ok, "no joint states from the bridge:\n" + bridge.log()
    yield dev, bridge, node, pub, got
    node.destroy_node()
    rc = bridge.stop()
    dev.stop()
    assert rc == 0, bridge.log()


def drive(node, pub, data, seconds):
    t_end = time.monotonic() + seconds
    while time.monotonic() < t_end:
        pub.publish(Float64MultiArray(data=data))
        spin_until(node, lambda: False, timeout=0.05)


def test_round_trip_commands_to_valves_and_sensors_to_joint_states(rig):
    dev, bridge, node, pub, got = rig
    drive(node, pub, [2.0, -0.191, 0.2], 1.0)
    cmds = [m for _, m in dev.last_commands()]
    assert cmds[0].is_stop                          # the first frame on the link is a stop
    assert cmds[-1] == CommandFrame(2.0, 1, 1, True)
    assert dev.plant.valve_boom == 1 and dev.plant.valve_bucket == 1
    js = got["js"][-1]
    assert list(js.name) == ["boom", "bucket", "wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr"]
    # the boom lifts (negative) and the bucket curls while the valves are open
    assert js.position[0] < -0.05 and js.position[1] > 0.05
    assert js.velocity[0] == pytest.approx(-0.191, abs=2e-3) and js.velocity[1] == pytest.approx(0.2, abs=2e-3)
    assert js.velocity[2] == pytest.approx(2.0, abs=0.1) and js.velocity[4] == js.velocity[5]
    assert all(math.isnan(p) for p in js.position[2:])
    assert got["drift"] and got["front"] and got["rear"]
    assert not any(got["front"][-5:])               # no injected drift, currents below presets


def test_unsafe_and_malformed_commands_never_move_the_machine(rig):
    dev, bridge, node, pub, got = rig
    drive(node, pub, [-1.0, 0.191, -0.2], 0.5)      # reverse, lower boom, tilt forward
    assert dev.last_commands()[-1][1] == CommandFrame(0.0, 0, 0, True)
    n_before = len(dev.last_commands())
    drive(node, pub, [float("nan"), 0.0, 0.0], 0.3)
    drive(node, pub, [1.0, 0.0], 0.3)
    # rejected: the watchdog (no *valid* command) stops the machine
    assert dev.last_commands()[-1][1].is_stop and len(dev.last_commands()) > n_before
    ok = spin_until(node, lambda: any(kv.key == "rejected_commands" and int(kv.value) >= 2
                                      for d in got["diag"] for s in d.status for kv in s.values), timeout=3.0)
    assert ok


def test_watchdog_sends_stop_within_300_ms_of_the_last_command(rig):
    dev, bridge, node, pub, got = rig
    drive(node, pub, [2.0, -0.191, 0.2], 0.8)
    t_last = time.monotonic()
    pub.publish(Float64MultiArray(data=[2.0, -0.191, 0.2]))
    spin_until(node, lambda: False, timeout=0.8)
    frames = [(t, m) for t, m in dev.last_commands() if t > t_last]
    moving = [t for t, m in frames if not m.is_stop]
    t_move_end = max(moving) if moving else t_last
    first_stop = min(t for t, m in frames if m.is_stop and t > t_move_end)
    # 300 ms timeout (from the command's arrival) + the 5 ms watchdog tick + margin for DDS
    # delivery and this 2-core machine's scheduling (measured: 303-307 ms)
    assert first_stop - t_last < 0.3 + 0.005 + 0.05, first_stop - t_last
    assert first_stop - t_last >= 0.25
    assert dev.plant.wheel_setpoint == 0.0 and dev.plant.valve_boom == 0


def test_unplug_and_replug_reconnects_and_sends_stop_first(rig):
    dev, bridge, node, pub, got = rig
    drive(node, pub, [2.0, -0.191, 0.2], 0.5)
    dev.unplug()
    drive(node, pub, [2.0, -0.191, 0.2], 1.0)       # commands keep coming while unplugged
    n = len(dev.received)
    dev.plug()
    drive(node, pub, [2.0, -0.191, 0.2], 2.5)       # backoff, reopen, then commands again
    after = [m for _, m in dev.received[n:] if isinstance(m, CommandFrame)]
    assert after, "the bridge did not reconnect:\n" + bridge.log()
    assert after[0].is_stop                          # first thing on the new link
    assert after[-1] == CommandFrame(2.0, 1, 1, True)  # and it carries on with fresh commands
    assert bridge.alive()
    n_js = len(got["js"])
    spin_until(node, lambda: len(got["js"]) > n_js + 10, timeout=2.0)
    assert len(got["js"]) > n_js + 10


def test_injected_drift_is_reported(ros, tmp_path):
    link = str(tmp_path / "due")
    dev = FakeDue(link=link, drift_front=True).start()
    bridge = RosProcess("lhd_hw_bridge.bridge_node", {"port": link}, tmp_path / "bridge.log")
    node = rclpy.create_node("drift_test")
    front, rear = [], []
    node.create_subscription(Bool, "/lhd/wheel_drift/front", lambda m: front.append(m.data), 50)
    node.create_subscription(Bool, "/lhd/wheel_drift/rear", lambda m: rear.append(m.data), 50)
    try:
        assert spin_until(node, lambda: len(front) > 20, timeout=20.0), bridge.log()
        assert all(front[-10:]) and not any(rear[-10:])
    finally:
        node.destroy_node()
        bridge.stop()
        dev.stop()


def test_emulator_cli_and_bridge_as_two_processes(ros, tmp_path):
    """`lhd-fake-due` and `bridge_node` as separate processes on one pty, as a user runs them."""
    import signal
    import subprocess
    import sys

    link = str(tmp_path / "due")
    emu = subprocess.Popen([sys.executable, "-m", "lhd_hw_bridge.fake_due", "--link", link, "--noise", "0.5"],
                           stdout=subprocess.PIPE, text=True)
    line = emu.stdout.readline()
    assert "fake Due on /dev/pts/" in line and link in line
    bridge = RosProcess("lhd_hw_bridge.bridge_node", {"port": link}, tmp_path / "bridge.log")
    node = rclpy.create_node("two_proc_test")
    js = []
    node.create_subscription(JointState, "/lhd/joint_states", lambda m: js.append(m), 50)
    try:
        assert spin_until(node, lambda: len(js) > 50, timeout=20.0), bridge.log()
    finally:
        node.destroy_node()
        assert bridge.stop() == 0
        emu.send_signal(signal.SIGTERM)
        assert emu.wait(5) == 0


def test_bridge_parser_benchmark_runs():
    from lhd_hw_bridge.bench import parser_throughput

    assert parser_throughput(2000) > 1000.0


def test_drift_from_odometry_speed_mismatch(rig):
    """Wheels turning at 2 rad/s (0.27 m/s at the rim) while /lhd/odom says the machine stands."""
    from nav_msgs.msg import Odometry
    from rclpy.qos import qos_profile_sensor_data

    dev, bridge, node, pub, got = rig
    pub_odom = node.create_publisher(Odometry, "/lhd/odom", qos_profile_sensor_data)
    t_end = time.monotonic() + 1.5
    while time.monotonic() < t_end:
        pub.publish(Float64MultiArray(data=[2.0, 0.0, 0.0]))
        pub_odom.publish(Odometry())  # twist.linear.x = 0
        spin_until(node, lambda: False, timeout=0.05)
    assert all(got["front"][-5:]) and all(got["rear"][-5:]) and all(got["drift"][-5:])
    # the machine moves with its wheels: no drift
    t_end = time.monotonic() + 1.0
    while time.monotonic() < t_end:
        pub.publish(Float64MultiArray(data=[2.0, 0.0, 0.0]))
        o = Odometry()
        o.twist.twist.linear.x = 2.0 * 0.137
        pub_odom.publish(o)
        spin_until(node, lambda: False, timeout=0.05)
    assert not any(got["front"][-5:]) and not any(got["rear"][-5:])


def test_corrupted_and_dropped_frames_are_counted_and_the_link_carries_on(ros, tmp_path):
    link = str(tmp_path / "due")
    dev = FakeDue(link=link, corrupt=0.2, drop=0.1, noise=1.0, seed=3).start()
    bridge = RosProcess("lhd_hw_bridge.bridge_node", {"port": link}, tmp_path / "bridge.log")
    node = rclpy.create_node("noise_test")
    js, diag = [], []
    node.create_subscription(JointState, "/lhd/joint_states", js.append, 50)
    node.create_subscription(DiagnosticArray, "/diagnostics", diag.append, 10)

    def counts():
        for d in reversed(diag):
            for s in d.status:
                kv = {k.key: k.value for k in s.values}
                return int(kv["crc_errors"]) + int(kv["framing_errors"]), int(kv["sequence_gaps"])
        return 0, 0

    try:
        assert spin_until(node, lambda: len(js) > 100 and counts()[0] > 5 and counts()[1] > 5, timeout=20.0), \
            bridge.log()
        assert bridge.alive()
    finally:
        node.destroy_node()
        assert bridge.stop() == 0
        dev.stop()
