"""The bridge node as a real process, over real DDS, against the device emulator on a real
pseudo-terminal: round trip, safety, watchdog timing, unplug / re-plug, parameters (start and
run time), use_sim_time, namespace, exclusive port, cumulative counters, device status."""
import math
import os
import time

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64, Float64MultiArray

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
    got = {"js": [], "drift": [], "front": [], "rear": [], "diag": [], "mass": []}
    node.create_subscription(JointState, "/lhd/joint_states", lambda m: got["js"].append(m), 50)
    node.create_subscription(Bool, "/lhd/wheel_drift", lambda m: got["drift"].append(m.data), 50)
    node.create_subscription(Bool, "/lhd/wheel_drift/front", lambda m: got["front"].append(m.data), 50)
    node.create_subscription(Bool, "/lhd/wheel_drift/rear", lambda m: got["rear"].append(m.data), 50)
    node.create_subscription(DiagnosticArray, "/diagnostics", lambda m: got["diag"].append(m), 10)
    node.create_subscription(Float64, "/lhd/load_cell/mass", lambda m: got["mass"].append(m.data), 10)
    pub = node.create_publisher(Float64MultiArray, "/lhd/cmd", 1)
    ok = spin_until(node, lambda: len(got["js"]) > 5, timeout=20.0)
    assert ok, "no joint states from the bridge:\n" + bridge.log()
    fresh_start(node, pub, got)                # the fresh start the bridge waits for (the mux's idle zeros)
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


def fresh_start(node, pub, got, timeout: float = 10.0) -> None:
    """The all-zero command the bridge awaits after a fault (the mux's idle zeros, a released trigger), sent
    until its diagnostics say it awaits none. Zeros for a fixed 0.2 s, then 0.3 s of motion, twice ended with a
    stop frame last on a busy 2-core machine (CI, 2026-11-30). Not pinned down; two candidates: the bridge's
    command subscription keeps only the newest message (COMMAND_QOS), so a bridge that does not spin for the
    whole burst takes the next motion command instead; and the device's emulator, a thread of this test
    process, reads its pty late when the process is starved. Both are on the safe side (stopped)."""
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        n = len(got["diag"])
        drive(node, pub, [0.0, 0.0, 0.0], 0.1)
        if spin_until(node, lambda: any(s.name.endswith("device") and status_values(s).get("awaiting_zero_command")
                                        == "False" for d in got["diag"][n:] for s in d.status), timeout=0.5):
            return
    pytest.fail(f"the bridge still awaits an all-zero command after {timeout:g} s of them: {device_status(got)}")


def drive_until_moving(node, pub, dev, bridge, data, frame, timeout: float = 3.0) -> None:
    """After a fresh start: `data` until the device's newest command frame is `frame` (motion), within
    `timeout` (see fresh_start: a fixed 0.3 s was not always enough on a busy machine)."""
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        drive(node, pub, data, 0.1)
        if dev.last_commands() and dev.last_commands()[-1][1] == frame:
            return
    pytest.fail(f"no {frame} within {timeout:g} s of {data} after the fresh start; the device's last frames "
                f"{dev.last_commands()[-5:]}\n{bridge.log()[-3000:]}")


def test_round_trip_commands_to_valves_and_sensors_to_joint_states(rig):
    dev, bridge, node, pub, got = rig
    drive(node, pub, [2.0, -0.191, 0.2], 1.0)
    # the emulated wheels follow with a first-order lag from the first command frame on, which a
    # loaded machine may deliver late: keep commanding until they are near the set-point (3 s at most)
    t_end = time.monotonic() + 3.0
    while abs(got["js"][-1].velocity[2] - 2.0) > 0.05 and time.monotonic() < t_end:
        drive(node, pub, [2.0, -0.191, 0.2], 0.1)
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
    # the wheels' angles integrated from their speeds: finite, and turned forward (no NaN on a topic)
    assert all(math.isfinite(p) for p in js.position) and js.position[2] > 0.5 and js.position[4] == js.position[5]
    assert got["drift"] and got["front"] and got["rear"]
    assert not any(got["front"][-5:])               # no injected drift, currents below presets
    # a device without the load cell (the emulator's default, as an older firmware): no mass, and
    # the load cell is reported as absent, not as a fault
    def load_cell():
        return [s for d in got["diag"] for s in d.status if s.name.endswith(": load_cell")]
    assert spin_until(node, lambda: load_cell(), timeout=3.0)
    st = load_cell()[-1]
    assert st.level == DiagnosticStatus.OK and st.message.startswith("no load cell"), st.message
    assert got["mass"] == []


def test_unsafe_and_malformed_commands_never_move_the_machine(rig):
    dev, bridge, node, pub, got = rig
    drive(node, pub, [-1.0, 0.191, -0.2], 0.5)      # reverse, lower boom, tilt forward
    assert dev.last_commands()[-1][1] == CommandFrame(0.0, 0, 0, True)
    n_before = len(dev.last_commands())
    drive(node, pub, [float("nan"), 0.0, 0.0], 0.3)
    drive(node, pub, [1.0, 0.0], 0.3)
    # rejected: a stop at once, and the watchdog (no *valid* command) keeps it stopped
    assert dev.last_commands()[-1][1].is_stop and len(dev.last_commands()) > n_before
    ok = spin_until(node, lambda: any(kv.key == "rejected_commands" and int(kv.value) >= 2
                                      for d in got["diag"] for s in d.status for kv in s.values), timeout=3.0)
    assert ok


def test_a_rejected_command_stops_the_machine_at_once(rig):
    """A NaN command after valid ones: the stop leaves at once, not at the watchdog 0.3 s later on
    the last valid command (a review, 2026-11-28: 12 more motion frames, the stop 0.245 s later);
    the next valid command moves the machine again."""
    dev, bridge, node, pub, got = rig
    drive(node, pub, [2.0, -0.191, 0.2], 0.5)
    assert not dev.last_commands()[-1][1].is_stop
    t_bad = time.monotonic()
    pub.publish(Float64MultiArray(data=[float("nan"), 0.0, 0.0]))
    spin_until(node, lambda: False, timeout=0.25)
    after = [(t, m) for t, m in dev.last_commands() if t > t_bad]
    first_stop = min(t for t, m in after if m.is_stop) - t_bad
    assert first_stop < 0.1, first_stop                 # DDS delivery and a loaded machine, not 0.3 s
    assert not any(not m.is_stop for t, m in after if t > t_bad + first_stop), "motion after the stop"
    drive(node, pub, [2.0, -0.191, 0.2], 0.3)
    assert dev.last_commands()[-1][1] == CommandFrame(2.0, 1, 1, True)


def test_a_silent_device_is_sent_stops_and_bytes_without_frames_are_named(rig):
    """The device stops sending sensor frames while commands keep coming: after cmd_timeout (0.3 s)
    without one the bridge sends stops, and says so; garbage on the line (what a wrong baud rate
    gives) is named as such; frames again and an all-zero command: motion again."""
    dev, bridge, node, pub, got = rig
    drive(node, pub, [2.0, -0.191, 0.2], 0.5)
    t_mute = time.monotonic()
    dev.silent = True
    t_end = time.monotonic() + 2.5
    while time.monotonic() < t_end:
        pub.publish(Float64MultiArray(data=[2.0, -0.191, 0.2]))
        dev.send_raw(bytes([0x41, 0x7E, 0x13, 0xFF, 0x00]) * 8)     # bytes, never a valid frame
        spin_until(node, lambda: False, timeout=0.05)
    after = [(t, m) for t, m in dev.last_commands() if t > t_mute]
    moving = [t - t_mute for t, m in after if not m.is_stop]
    assert after and after[-1][1].is_stop
    # cmd_timeout after the last frame the bridge read, plus the host's scheduling: both the bridge's reader (when it
    # took the last frame) and the fake device's (when it stamps a command) run late on a loaded host; 0.419 s with
    # five CPU-bound processes on two cores (2026-12-01), under 0.4 s otherwise
    assert not moving or max(moving) < 0.3 + 0.05 + 0.1, max(moving)
    st = link_status(got)
    assert st["level"] == DiagnosticStatus.ERROR and "but make no valid frame" in st["message"] and \
        "wrong baud rate (115200)" in st["message"], st
    dev.silent = False
    fresh_start(node, pub, got)                     # frames again, and the fresh start a silence needs: motion again
    drive_until_moving(node, pub, dev, bridge, [2.0, -0.191, 0.2], CommandFrame(2.0, 1, 1, True))


def stop_delay(dev, node, pub, wait=0.8) -> float:
    """Seconds from the last published command to the first stop frame at the device."""
    drive(node, pub, [2.0, -0.191, 0.2], 0.8)
    t_last = time.monotonic()
    pub.publish(Float64MultiArray(data=[2.0, -0.191, 0.2]))
    spin_until(node, lambda: False, timeout=wait)
    frames = [(t, m) for t, m in dev.last_commands() if t > t_last]
    moving = [t for t, m in frames if not m.is_stop]
    t_move_end = max(moving) if moving else t_last
    return min(t for t, m in frames if m.is_stop and t > t_move_end) - t_last


def test_watchdog_sends_stop_within_300_ms_of_the_last_command(rig):
    dev, bridge, node, pub, got = rig
    delay = stop_delay(dev, node, pub)
    # 300 ms timeout (from the command's arrival) + the 5 ms watchdog tick + margin for DDS
    # delivery and this 2-core machine's scheduling (measured: 303-307 ms)
    assert 0.25 <= delay < 0.3 + 0.005 + 0.05, delay
    assert dev.plant.wheel_setpoint == 0.0 and dev.plant.valve_boom == 0


def test_unplug_and_replug_reconnects_and_sends_stop_first(rig):
    dev, bridge, node, pub, got = rig
    drive(node, pub, [2.0, -0.191, 0.2], 0.5)
    dev.unplug()
    drive(node, pub, [2.0, -0.191, 0.2], 1.0)       # commands keep coming while unplugged
    n = len(dev.received)
    dev.plug()
    drive(node, pub, [2.0, -0.191, 0.2], 2.5)       # backoff, reopen; the same commands keep coming
    after = [m for _, m in dev.received[n:] if isinstance(m, CommandFrame)]
    assert after, "the bridge did not reconnect:\n" + bridge.log()
    assert after[0].is_stop                          # first thing on the new link
    # the stream that went on through the unplug does not restart the machine (2026-11-30): stops only,
    # until an all-zero command (the mux's idle zeros, a released trigger), then fresh commands move it
    assert all(m.is_stop for m in after), after[-3:]
    fresh_start(node, pub, got)
    drive_until_moving(node, pub, dev, bridge, [2.0, -0.191, 0.2], CommandFrame(2.0, 1, 1, True))
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


def test_drift_from_odometry_travel_mismatch(rig):
    """Wheels turning at 2 rad/s (0.27 m/s at the rim) while /lhd/odom, stamped at each image's instant,
    says the machine stands: drift on both axles; then the machine moving with the wheels: none. The
    bridge compares travels over the policy's period (bridge_core.DriftWindow), and the machine's
    travel is the odometry's speed integrated between its stamps."""
    from nav_msgs.msg import Odometry
    from rclpy.qos import qos_profile_sensor_data

    dev, bridge, node, pub, got = rig
    pub_odom = node.create_publisher(Odometry, "/lhd/odom", qos_profile_sensor_data)

    def odom(v: float) -> Odometry:
        o = Odometry()
        o.header.stamp = node.get_clock().now().to_msg()
        o.pose.pose.orientation.w = 1.0
        o.twist.twist.linear.x = v
        return o

    t_end = time.monotonic() + 1.5
    while time.monotonic() < t_end:
        pub.publish(Float64MultiArray(data=[2.0, 0.0, 0.0]))
        pub_odom.publish(odom(0.0))
        spin_until(node, lambda: False, timeout=0.03)
    assert all(got["front"][-5:]) and all(got["rear"][-5:]) and all(got["drift"][-5:])
    # the machine moves with its wheels: no drift
    t_end = time.monotonic() + 1.0
    while time.monotonic() < t_end:
        pub.publish(Float64MultiArray(data=[2.0, 0.0, 0.0]))
        pub_odom.publish(odom(2.0 * 0.137))
        spin_until(node, lambda: False, timeout=0.03)
    assert not any(got["front"][-5:]) and not any(got["rear"][-5:])


def test_odometry_on_another_clock_is_named_and_the_currents_decide(rig):
    """/lhd/odom stamped on a clock 1,000 s behind the bridge's (a camera driver's own time base, or
    use_sim_time on one side): its stamps never meet the wheel frames, so the drift flags come from the
    motor currents, and the serial link's diagnostics say why with a WARN instead of going quiet."""
    from nav_msgs.msg import Odometry
    from rclpy.qos import qos_profile_sensor_data

    dev, bridge, node, pub, got = rig
    pub_odom = node.create_publisher(Odometry, "/lhd/odom", qos_profile_sensor_data)

    def link():
        return [s for d in got["diag"] for s in d.status if s.name.endswith(": serial link")]

    t_end = time.monotonic() + 2.5
    while time.monotonic() < t_end:
        pub.publish(Float64MultiArray(data=[2.0, 0.0, 0.0]))
        o = Odometry()
        now_ns = node.get_clock().now().nanoseconds - 1_000 * 10**9
        o.header.stamp.sec, o.header.stamp.nanosec = divmod(now_ns, 10**9)
        o.pose.pose.orientation.w = 1.0
        pub_odom.publish(o)           # a machine that stands: drift by travel, were the stamps usable
        spin_until(node, lambda: False, timeout=0.03)
    st = link()[-1]
    assert st.level == DiagnosticStatus.WARN and "drift from the motor currents only" in st.message, st.message
    assert "older than the newest wheel frame" in {kv.key: kv.value for kv in st.values}["drift_from"]
    assert not any(got["front"][-5:])     # the emulator's currents sit under the presets: no drift


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


# ---------------------------------------------------------------- parameters, clock, namespace
def status_values(msg) -> dict:
    return {kv.key: kv.value for kv in msg.values}


def named_status(got, name: str) -> dict:
    """The newest status on /diagnostics whose name ends with `name`: level, message and values."""
    for d in reversed(got["diag"]):
        for s in d.status:
            if s.name.endswith(name):
                return {"level": s.level, "message": s.message, **status_values(s)}
    return {}


def device_status(got) -> dict:
    return named_status(got, "device")


def link_status(got) -> dict:
    return named_status(got, "serial link")


@pytest.mark.parametrize("name, value, needle", [
    ("valve_deadband", 0.0, "'valve_deadband' = 0.0 is invalid: a zero command would open the valves"),
    ("command_rate_hz", 10.0, "one lost command frame would leave the device 200 ms without a command, more than "
                              "half its 250 ms watchdog (it would stop the machine); expected >= 16 Hz"),
    ("cmd_timeout", 2.0, "'cmd_timeout' = 2.0 is invalid: out of range; expected a number in [0.01, 1.0]"),
    ("baud", "fast", "'baud' = 'fast' is invalid; expected an integer"),
    ("port", "''", "'port' = '' is invalid: is empty: expected the Due's serial device, e.g. /dev/ttyACM0"),
    ("baud", 1200, "'baud' = 1200 is invalid: 1200 baud erases the Arduino Due's firmware when the port closes"),
])
def test_unsafe_or_wrong_parameters_end_the_node_with_one_line_and_exit_2(ros, tmp_path, name, value, needle):
    bridge = RosProcess("lhd_hw_bridge.bridge_node", {"port": str(tmp_path / "none"), name: value},
                        tmp_path / "bridge.log")
    assert bridge.proc.wait(30) == 2, bridge.log()
    log = bridge.log()
    assert needle in log and "Traceback" not in log, log


def test_values_of_the_other_numeric_type_are_taken(ros, tmp_path):
    """`-p baud:=115200.0` (float for an int), `-p cmd_timeout:=1` and `-p command_rate_hz:=100`
    (ints for floats) run the node, and the rate is really 100 Hz at the device."""
    link = str(tmp_path / "due")
    dev = FakeDue(link=link).start()
    bridge = RosProcess("lhd_hw_bridge.bridge_node", {"port": link, "baud": "115200.0", "cmd_timeout": 1,
                                                      "command_rate_hz": 100}, tmp_path / "bridge.log")
    node = rclpy.create_node("numeric_types_test")
    js = []
    node.create_subscription(JointState, "/lhd/joint_states", js.append, 50)
    try:
        assert spin_until(node, lambda: len(js) > 20, timeout=20.0), bridge.log()
        n0, t0 = len(dev.last_commands()), time.monotonic()
        spin_until(node, lambda: False, timeout=1.0)
        rate = (len(dev.last_commands()) - n0) / (time.monotonic() - t0)
        assert 80.0 < rate < 120.0, rate
    finally:
        node.destroy_node()
        assert bridge.stop() == 0, bridge.log()
        dev.stop()


def set_params(node, params):
    from rclpy.parameter_client import AsyncParameterClient

    client = AsyncParameterClient(node, "lhd_hw_bridge")
    assert client.wait_for_services(10.0)
    fut = client.set_parameters(params)
    spin_until(node, fut.done, timeout=10.0)
    return fut.result().results


def test_runtime_parameter_changes_take_effect_or_are_refused_with_the_reason(rig):
    from rclpy.parameter import Parameter

    dev, bridge, node, pub, got = rig
    refused = {"valve_deadband": (0.0, "a zero command would open the valves"),
               "command_rate_hz": (5.0, "expected >= 16 Hz"),
               "cmd_timeout": (5.0, "out of range"),
               "port": ("/dev/ttyS0", "read-only"),
               "boom_zero": (2.0, "in rad, not deg"),               # 2 deg typed as rad: 115 deg
               "bucket_zero": (float("nan"), "expected a number")}
    for name, (value, why) in refused.items():
        r, = set_params(node, [Parameter(name, value=value)])
        assert not r.successful and why in r.reason, (name, r.reason)
    # the arm's zeros (the angles the device reports in the attack pose) are taken off every joint state from now
    # on; the device's own angles and the zeros are in its status, for the calibration
    r = set_params(node, [Parameter("boom_zero", value=0.05), Parameter("bucket_zero", value=-0.03)])
    assert all(x.successful for x in r), [x.reason for x in r]
    n0 = len(got["js"])
    assert spin_until(node, lambda: len(got["js"]) > n0 + 10, timeout=5.0)
    js = got["js"][-1]
    assert js.position[0] == pytest.approx(dev.plant.boom - 0.05, abs=0.006), (js.position[0], dev.plant.boom)
    assert js.position[1] == pytest.approx(dev.plant.bucket + 0.03, abs=0.006), (js.position[1], dev.plant.bucket)
    assert spin_until(node, lambda: device_status(got).get("boom_zero_rad") == "0.05", timeout=5.0)
    assert device_status(got)["bucket_zero_rad"] == "-0.03"
    assert float(device_status(got)["boom_angle_device_rad"]) == pytest.approx(dev.plant.boom, abs=0.006)
    # a longer command timeout, given as an int for a float, is applied: the stop now comes ~600 ms after
    r, = set_params(node, [Parameter("cmd_timeout", value=0.6)])
    assert r.successful, r.reason
    delay = stop_delay(dev, node, pub, wait=1.2)
    assert 0.55 <= delay < 0.6 + 0.005 + 0.05, delay
    # a slower command rate is applied at the device
    r, = set_params(node, [Parameter("command_rate_hz", value=25)])
    assert r.successful, r.reason
    n0, t0 = len(dev.last_commands()), time.monotonic()
    spin_until(node, lambda: False, timeout=1.0)
    rate = (len(dev.last_commands()) - n0) / (time.monotonic() - t0)
    assert 20.0 < rate < 30.0, rate


def test_watchdog_stops_the_machine_with_use_sim_time_and_no_clock(ros, tmp_path):
    """Nothing publishes /clock: the node's clock stands still, its steady timers must not."""
    link = str(tmp_path / "due")
    dev = FakeDue(link=link).start()
    bridge = RosProcess("lhd_hw_bridge.bridge_node", {"port": link, "use_sim_time": "true"}, tmp_path / "bridge.log")
    node = rclpy.create_node("sim_time_test")
    pub = node.create_publisher(Float64MultiArray, "/lhd/cmd", 1)
    js = []
    node.create_subscription(JointState, "/lhd/joint_states", js.append, 50)
    try:
        assert spin_until(node, lambda: len(js) > 5, timeout=20.0), bridge.log()
        drive(node, pub, [0.0, 0.0, 0.0], 0.2)             # the fresh start after the bridge started
        delay = stop_delay(dev, node, pub)
        assert 0.25 <= delay < 0.3 + 0.005 + 0.05, delay
        assert any(not m.is_stop for _, m in dev.last_commands())      # the commands did reach the device
    finally:
        node.destroy_node()
        assert bridge.stop() == 0, bridge.log()
        dev.stop()


def test_topics_follow_the_node_namespace(ros, tmp_path):
    """`--ros-args -r __ns:=/lhd2`: every topic of this machine under /lhd2, nothing under /lhd.
    (RosProcess has no way to pass a remap, hence the plain process here.)"""
    import signal
    import subprocess
    import sys

    link = str(tmp_path / "due")
    dev = FakeDue(link=link).start()
    log = open(tmp_path / "bridge.log", "w")
    proc = subprocess.Popen([sys.executable, "-m", "lhd_hw_bridge.bridge_node", "--ros-args", "-r", "__ns:=/lhd2",
                             "-p", f"port:={link}"], stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    node = rclpy.create_node("namespace_test")
    got = {"/lhd2/joint_states": [], "/lhd/joint_states": [], "/lhd2/hw/status": []}
    node.create_subscription(JointState, "/lhd2/joint_states", got["/lhd2/joint_states"].append, 50)
    node.create_subscription(JointState, "/lhd/joint_states", got["/lhd/joint_states"].append, 50)
    node.create_subscription(DiagnosticStatus, "/lhd2/hw/status", got["/lhd2/hw/status"].append, 10)
    pub = node.create_publisher(Float64MultiArray, "/lhd2/cmd", 1)
    try:
        assert spin_until(node, lambda: len(got["/lhd2/joint_states"]) > 20 and got["/lhd2/hw/status"], 20.0), \
            (tmp_path / "bridge.log").read_text()
        drive(node, pub, [0.0, 0.0, 0.0], 0.2)
        drive(node, pub, [1.0, 0.0, 0.0], 0.5)
        assert dev.last_commands()[-1][1] == CommandFrame(1.0, 0, 0, True)
        assert got["/lhd/joint_states"] == []
    finally:
        node.destroy_node()
        os.killpg(proc.pid, signal.SIGINT)
        assert proc.wait(10) == 0
        log.close()
        dev.stop()


# ---------------------------------------------------------------- port, counters, device status
def test_a_second_bridge_on_the_same_port_is_refused_and_says_why(rig, tmp_path):
    dev, bridge, node, pub, got = rig
    link = dev.link
    second = RosProcess("lhd_hw_bridge.bridge_node", {"port": link}, tmp_path / "second.log")
    try:
        def refused():
            return any(s.level == DiagnosticStatus.ERROR and "in use by another process" in s.message
                       for d in got["diag"] for s in d.status)
        assert spin_until(node, refused, timeout=20.0), second.log()
        gaps0, n0, t0 = dev.parser.seq_gaps, len(dev.last_commands()), time.monotonic()
        drive(node, pub, [1.0, 0.0, 0.0], 2.0)
        rate = (len(dev.last_commands()) - n0) / (time.monotonic() - t0)
        assert 40.0 < rate < 60.0, rate                    # one writer at 50 Hz, not two
        assert dev.parser.seq_gaps == gaps0                # one numbering: nobody else writes
        assert second.alive()                              # and it keeps retrying
    finally:
        assert second.stop() == 0, second.log()


def test_error_counters_survive_a_reconnect_and_unknown_types_are_counted(rig):
    from lhd_hw_bridge.protocol import frame_bytes

    dev, bridge, node, pub, got = rig
    dev.corrupt = 0.3
    assert spin_until(node, lambda: int(link_status(got).get("crc_errors", 0)) >= 5, timeout=10.0)
    dev.corrupt = 0.0
    spin_until(node, lambda: False, timeout=0.2)
    before = {k: int(link_status(got)[k]) for k in ("crc_errors", "framing_errors", "sequence_gaps")}
    dev.unplug()
    spin_until(node, lambda: link_status(got).get("connected") == "False", timeout=5.0)
    dev.plug()
    assert spin_until(node, lambda: link_status(got).get("reconnects") == "1" and
                      link_status(got).get("connected") == "True", timeout=10.0)
    for seq in range(3):
        dev.send_raw(frame_bytes(0x7E, seq, b"later"))
    assert spin_until(node, lambda: link_status(got).get("unknown_types") == "3", timeout=5.0), link_status(got)
    after = link_status(got)
    assert all(int(after[k]) >= v for k, v in before.items()), (before, after)


def test_estop_currents_and_valve_states_are_published(rig):
    dev, bridge, node, pub, got = rig
    hw = []
    node.create_subscription(DiagnosticStatus, "/lhd/hw/status", hw.append, 50)
    dev.currents = (4.321, 5.5, 12.345)
    drive(node, pub, [1.0, -0.191, 0.2], 0.5)
    assert spin_until(node, lambda: hw and status_values(hw[-1])["valve_boom"] == "1", timeout=5.0)
    v = status_values(hw[-1])
    assert hw[-1].level == DiagnosticStatus.OK and v["drive_enabled"] == "True" and v["estop"] == "False"
    assert (v["current_fl_A"], v["current_fr_A"], v["current_rear_A"], v["valve_bucket"]) == \
        ("4.321", "5.5", "12.345", "1")
    dev.estop = True
    drive(node, pub, [1.0, -0.191, 0.2], 0.5)               # the policy keeps commanding
    last = hw[-1]
    assert last.level == DiagnosticStatus.ERROR and "emergency stop" in last.message
    assert status_values(last)["estop"] == "True" and status_values(last)["valve_boom"] == "0"
    assert all(m.is_stop for _, m in dev.last_commands()[-10:])   # the host sends stop frames meanwhile
    assert spin_until(node, lambda: any(s.level == DiagnosticStatus.ERROR and s.name.endswith("device")
                                        and "emergency stop" in s.message for d in got["diag"][-2:]
                                        for s in d.status), timeout=3.0)
    dev.estop = False
    drive(node, pub, [1.0, -0.191, 0.2], 0.5)               # released: the stream alone restarts nothing
    assert all(m.is_stop for _, m in dev.last_commands()[-10:]) and dev.plant.valve_boom == 0
    assert not dev.held                                     # the bridge's stop frames cleared the device's hold
    # ERROR while a command asks for motion that is withheld: the supervisor ends a running attempt on it
    assert spin_until(node, lambda: hw and hw[-1].level == DiagnosticStatus.ERROR
                      and "it moves again after an all-zero command" in hw[-1].message
                      and status_values(hw[-1])["awaiting_zero_command"] == "True", timeout=3.0), hw[-1].message
    # a command the mapper turns into no motion is not the fresh start: refused reverse / lowering / tilt, and
    # arm speeds under the valve dead band (a review, 2026-11-30: each restarted the machine)
    for cmd in ([-1.0, 0.191, -0.2], [0.0, -0.05, 0.05]):
        drive(node, pub, cmd, 0.2)
        drive(node, pub, [1.0, -0.191, 0.2], 0.3)
        assert all(m.is_stop for _, m in dev.last_commands()[-5:]), cmd
    fresh_start(node, pub, got)                             # the fresh start (a released trigger, the mux's zeros)
    drive_until_moving(node, pub, dev, bridge, [1.0, -0.191, 0.2], CommandFrame(1.0, 1, 1, True))
    drive(node, pub, [1.0, -0.191, 0.2], 0.3)
    assert hw[-1].level == DiagnosticStatus.OK and status_values(hw[-1])["valve_boom"] == "1"


def test_a_burst_of_late_frames_keeps_each_frames_measurement_instant(ros, tmp_path):
    """The device's frames held up for 0.25 s (USB, a busy host) arrive in one read. joint_states carried
    each frame's arrival until a review (2026-11-29, twelfth session): 25 frames measured over 0.24 s
    stamped within 3 ms, 0.24 rad of boom in 3 ms to anything that differentiates or aligns them. Each is
    now stamped at its measurement instant on the ROS clock (DeviceClock), 10 ms apart, never after its
    arrival. Device times of the burst continue the emulator's own clock."""
    from lhd_hw_bridge.protocol import SensorFrame, TxSequence

    link = str(tmp_path / "due")
    dev = FakeDue(link=link, rate=100.0, watchdog=0.25)
    t_start = time.monotonic()                      # the emulator's clock starts here (within a few ms)
    dev.start()
    bridge = RosProcess("lhd_hw_bridge.bridge_node", {"port": link}, tmp_path / "bridge.log")
    node = rclpy.create_node("bridge_burst_test")
    js = []
    node.create_subscription(JointState, "/lhd/joint_states", lambda m: js.append((time.monotonic(), m)), 500)
    try:
        assert spin_until(node, lambda: len(js) > 150, timeout=30.0), bridge.log()   # 1.5 s: the clock's window
        dev.silent = True
        t0 = time.monotonic()
        spin_until(node, lambda: False, timeout=0.25)
        tx, burst = TxSequence(), b""
        for k in range(25):                          # what the device measured during the stall
            burst += tx.encode(SensorFrame(int((t0 - t_start + k * 0.01) * 1e6), -0.5 - 0.001 * k, 0, 0, 0, 0, 0,
                                           0, 0, 0, 0, 0, 0, 1))
        n = len(js)
        dev.send_raw(burst)
        t_sent = time.monotonic()
        dev.silent = False
        assert spin_until(node, lambda: len(js) >= n + 25, timeout=5.0), bridge.log()
        got = [(t, m) for t, m in js[n:] if m.position[0] <= -0.5 + 1e-9]   # the burst's frames (boom -0.5..)
        assert len(got) == 25, len(got)
        stamps = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for _, m in got]
        gaps = [b - a for a, b in zip(stamps, stamps[1:])]
        assert all(abs(g - 0.01) < 0.002 for g in gaps), gaps                  # the device's 10 ms, not 0
        assert 0.23 < stamps[-1] - stamps[0] < 0.25
        # on the ROS clock (= monotonic + an offset here: the node and this test share the host's clock):
        # each frame measured when the stall let it be, not when it arrived
        ros_now = node.get_clock().now().nanoseconds * 1e-9
        assert stamps[-1] <= ros_now and (ros_now - stamps[0]) > 0.25 - 0.05 + (time.monotonic() - t_sent)
    finally:
        node.destroy_node()
        rc = bridge.stop()
        dev.stop()
    assert rc == 0, bridge.log()


def test_a_device_reset_while_running_holds_the_machine_and_reports_error(rig):
    """A review (2026-11-30): a Due reset (brown-out, its watchdog) was invisible to the host and the
    streamed command moved the machine again at once. The firmware now comes up held (flag bit 3);
    the bridge, seeing held after frames that were not, sends stop frames and reports ERROR for 1 s
    (the supervisor ends a running attempt on it), then takes only commands received after."""
    dev, bridge, node, pub, got = rig
    hw = []
    node.create_subscription(DiagnosticStatus, "/lhd/hw/status", hw.append, 50)
    drive(node, pub, [1.0, -0.191, 0.2], 0.5)
    assert dev.last_commands()[-1][1] == CommandFrame(1.0, 1, 1, True)
    n = len(dev.received)
    t_reset = time.monotonic()
    dev.reset()                                      # held and flagged reset until a stop frame
    drive(node, pub, [1.0, -0.191, 0.2], 0.7)        # the policy keeps commanding
    window = [(t, m) for t, m in dev.received[n:] if isinstance(m, CommandFrame)]
    assert window and all(m.is_stop for t, m in window if t - t_reset > 0.05), window[-5:]
    assert any(s.level == DiagnosticStatus.ERROR and "the device was reset" in s.message for s in hw), \
        [s.message for s in hw[-5:]]
    assert status_values([s for s in hw if "the device was reset" in s.message][-1])["device_resets"] == "1"
    assert not dev.held                              # the first stop frame cleared the device's hold
    drive(node, pub, [1.0, -0.191, 0.2], 1.0)        # past the 1 s hold, the same stream: still stopped
    assert all(m.is_stop for _, m in dev.last_commands()[-10:])
    fresh_start(node, pub, got)                      # the fresh start
    drive_until_moving(node, pub, dev, bridge, [1.0, -0.191, 0.2], CommandFrame(1.0, 1, 1, True))
    assert hw[-1].level == DiagnosticStatus.OK, hw[-1].message


def test_an_arm_sensor_fault_publishes_no_joint_state_and_stops(rig):
    """The firmware sends a NaN angle as -32768 with flag bit 4: the bridge publishes no joint state
    from such frames (no made-up angle), reports ERROR and sends stop frames; after the fault, the
    device is held until the bridge's stop frame, then fresh commands run."""
    dev, bridge, node, pub, got = rig
    hw = []
    node.create_subscription(DiagnosticStatus, "/lhd/hw/status", hw.append, 50)
    drive(node, pub, [1.0, -0.191, 0.2], 0.3)
    dev.boom_sensor_fault = True
    drive(node, pub, [1.0, -0.191, 0.2], 0.3)
    n_js, n_cmd = len(got["js"]), len(dev.received)
    drive(node, pub, [1.0, -0.191, 0.2], 0.5)
    assert len(got["js"]) == n_js, "joint states published from frames with a sensor fault"
    assert all(m.is_stop for _, m in dev.received[n_cmd:] if isinstance(m, CommandFrame))
    assert hw[-1].level == DiagnosticStatus.ERROR and "sensor fault on the device" in hw[-1].message, hw[-1].message
    assert dev.plant.valve_boom == 0 and dev.plant.wheel_setpoint == 0.0
    dev.boom_sensor_fault = False
    drive(node, pub, [1.0, -0.191, 0.2], 0.6)
    assert len(got["js"]) > n_js + 10 and all(math.isfinite(x) for x in got["js"][-1].position)
    assert all(m.is_stop for _, m in dev.last_commands()[-10:])       # no restart without a fresh start
    fresh_start(node, pub, got)
    drive_until_moving(node, pub, dev, bridge, [1.0, -0.191, 0.2], CommandFrame(1.0, 1, 1, True))


def test_a_silent_device_needs_the_fresh_start_when_its_frames_come_back(rig):
    """A review (2026-11-30): with the device's frames lost (a cable that carries the host's frames only), an
    e-stop pressed and released in the silence was never seen, the stop frames sent meanwhile cleared the
    device's hold, and the same stream moved the machine when the frames came back. Now a silence of the
    device needs the all-zero command too."""
    dev, bridge, node, pub, got = rig
    drive(node, pub, [1.0, -0.191, 0.2], 0.4)
    assert dev.last_commands()[-1][1] == CommandFrame(1.0, 1, 1, True)
    dev.silent = True
    drive(node, pub, [1.0, -0.191, 0.2], 1.2)                 # > 1 s without a frame: stop frames, a fresh start
    dev.estop = True
    drive(node, pub, [1.0, -0.191, 0.2], 0.2)
    dev.estop = False
    drive(node, pub, [1.0, -0.191, 0.2], 0.2)
    assert not dev.held                                       # the stop frames cleared the device's hold unseen
    dev.silent = False
    drive(node, pub, [1.0, -0.191, 0.2], 0.6)
    assert all(m.is_stop for _, m in dev.last_commands()[-10:])
    fresh_start(node, pub, got)
    drive_until_moving(node, pub, dev, bridge, [1.0, -0.191, 0.2], CommandFrame(1.0, 1, 1, True))
