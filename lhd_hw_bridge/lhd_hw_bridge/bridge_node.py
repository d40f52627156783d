"""`ros2 run lhd_hw_bridge bridge_node`: the LHD's Arduino Due over a serial link.

Topics live under the topic prefix (/lhd, or the node's namespace with `-r __ns:=/lhd2`).
Publishes what the sim node publishes (same names, SI units): <prefix>/joint_states,
<prefix>/wheel_drift, <prefix>/wheel_drift/front, <prefix>/wheel_drift/rear; the device's own
report on <prefix>/hw/status (diagnostic_msgs/DiagnosticStatus: e-stop and watchdog flags, motor
currents, valve states); when the device has the bucket's load cell (optional: load-cell frames,
type 0x04), <prefix>/load_cell/mass (std_msgs/Float64, kg) for valid frames only; and
/diagnostics (serial link, device, load_cell). Subscribes <prefix>/cmd
([u_wheels, u_boom, u_bucket] rad/s) and <prefix>/odom (the machine's speed at each image's instant: its
travel for drift detection, bridge_core.DriftWindow; on hardware it comes from the ArUco node).

Fail-safe behaviour (docs/hardware_bridge.md):
* every command goes through CommandMapper (no reverse wheels, no boom lowering, no bucket
  forward tilt; NaN / wrong length rejected and counted, and a stop frame sent at once);
* no valid command for cmd_timeout (0.3 s) -> stop frames (watchdog on arrival time, on the
  steady clock: use_sim_time cannot stop it);
* no sensor frame from the device for cmd_timeout (or none yet) -> stop frames: a device whose
  state is unknown is not driven; bytes that make no valid frame (a wrong baud rate) are named
  in /diagnostics;
* parameters that would defeat the safety (a dead band of 0, a command rate too slow for the
  device watchdog) are refused, at start (exit 2) and at run time (with the reason);
* the port is opened exclusively: a second bridge on it keeps retrying and says why in
  /diagnostics instead of writing too;
* serial loss -> reopen with exponential backoff inside the node; the first frame after a
  reconnection is a 0x00 and a stop; counters survive;
* while the device holds the machine (its emergency stop, held after a reset or a release, a
  sensor fault: flag bits 2-4), stop frames; a device reset seen (flag bit 5) -> stop frames and
  ERROR for DEVICE_RESET_HOLD_S, so the supervisor ends a running attempt; no joint state or drift
  flag from a frame with a sensor fault;
* after any of these (a reconnection, a hold, a reset) the machine moves again only once an all-zero
  command has come: a command stream that went on through the fault (a gamepad held, a controller
  outside the supervisor) does not restart the machine by itself (ISO 13850's reset is not a start);
* on shutdown a stop frame is sent before the port closes;
* a load-cell frame that is stale, saturated, not calibrated or not tared publishes no mass (the
  reason goes to /diagnostics, `load_cell`); the load cell never influences the commands.
"""
from __future__ import annotations

import dataclasses
import math
import threading
import time

import serial
from diagnostic_msgs.msg import DiagnosticStatus
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from rclpy.time import Time
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64, Float64MultiArray

from lhd_loading_ros.ros.diagnostics import ERROR, LEVEL_NAMES, OK, STALE, WARN, Diagnostics, status
from lhd_loading_ros.ros.params import Param, Params, steady_timer, topic_prefix
from lhd_loading_ros.ros.qos import COMMAND_QOS, MEASUREMENT_QOS
from lhd_loading_ros.ros.run import run_node
from lhd_loading_ros.task.config import load_config

from .bridge_core import (CMD_TIMEOUT_MAX, JOINT_NAMES, BridgeParams, CommandMapper, CommandRejected,
                          LoadCellMonitor, baud_problem, Watchdog, CommandScheduler, command_rate_problem,
                          deadband_problem,
                          WheelAngles, DeviceClock, DriftWindow, arm_zero_problem, detect_drift, joint_state_arrays)
from .protocol import (FLAG_ENABLED, FLAG_ESTOP, FLAG_HELD, FLAG_RESET, FLAG_SENSOR_FAULT, FLAG_WATCHDOG,
                       TYPE_LOAD_CELL, TYPE_SENSOR, CommandFrame, FrameParser, HeartbeatFrame, LoadCellFrame,
                       SensorFrame, TxSequence)

# Command frames at most every 2 ms: a 1 kHz teleop stream becomes <= 500 frames/s (about 6 kB/s, half
# of a 115,200-baud UART); a 5 ms watchdog tick with a little jitter still sends every changed command
MIN_FRAME_GAP = 0.002

# QoS (lhd_loading_ros.ros.qos): measurements and the device status MEASUREMENT_QOS (reliable,
# keep-last 5: matches reliable and best-effort subscribers; a short queue never delays fresh
# data behind stale data), commands COMMAND_QOS (reliable, keep-last 1: only the newest command
# matters, and losing it silently would let the watchdog stop the machine). Odometry in:
# sensor-data QoS (best effort), which accepts any publisher. The load cell's mass is a
# measurement too: MEASUREMENT_QOS (a late-joining supervisor gets the next 10 Hz frame, and a
# latched old mass would be wrong once the bucket is emptied).
WATCHDOG_TICK = 0.005   # s
STATUS_PERIOD = 0.1     # s, <prefix>/hw/status (and at once when the flags or valve states change)
DEVICE_STALE = 0.5      # s without a sensor frame: the device's report is no longer current
# s of stop frames and ERROR after the device was seen reset while this node ran (flag bit 5 newly set): the
# supervisor ends a running attempt on the ERROR, though the first stop frame clears the device's hold at once
DEVICE_RESET_HOLD_S = 1.0
# s without a sensor frame after which the machine moves again only after an all-zero command (a silence long
# enough for an e-stop press and release to go unseen); shorter gaps get stop frames only (device_silent)
SILENCE_FRESH_START_S = 1.0
LEVELS = {name: level for level, name in LEVEL_NAMES.items()}


def zero_motion(frame: CommandFrame) -> bool:
    """A command that moves nothing: the fresh start after a fault (BridgeNode.await_zero)."""
    return frame.wheel_setpoint == 0.0 and frame.valve_boom == 0 and frame.valve_bucket == 0


def open_problem(port: str, exc: Exception) -> str:
    """What a failed open means, for the log and /diagnostics."""
    if "exclusively lock" in str(exc):   # pyserial's message when flock(LOCK_EX) fails
        return f"{port} is in use by another process (it holds the port exclusively); not writing, retrying"
    return f"cannot open {port}: {exc}"


ARM_ZERO_WARNING = ("the measured tip and its pitch move with it (1 deg of boom: about 1.5 cm at the tip): set it "
                    "with the machine standing in the attack pose, never during an attempt")


class BridgeNode(Node):
    def __init__(self, cfg: dict | None = None, **node_kwargs):
        super().__init__("lhd_hw_bridge", **node_kwargs)
        config = Param("config", "", "lhd_params.yaml to read ('' = the one installed)")
        # the other parameters' defaults come from that file, so read it first (one Params per
        # node: rclpy chains the pre-set callbacks of several into duplicates)
        cfg_path = config.coerce(self.declare_parameter("config", "", ParameterDescriptor(dynamic_typing=True)).value)
        self.undeclare_parameter("config")
        base = BridgeParams.from_config(cfg if cfg is not None else load_config(cfg_path or None))
        wd = base.device_watchdog
        self.params = Params(self, [
            config,
            Param("port", "/dev/ttyACM0", "serial device of the Due (opened exclusively)",
                  check=lambda v: None if str(v).strip() else "is empty: expected the Due's serial device, e.g. "
                  "/dev/ttyACM0 (`ls /dev/ttyACM* /dev/serial/by-id/`)"),
            Param("baud", 115200, "baud rate (UART; the Due's native USB port ignores it, but not 1200)",
                  lo=1200, hi=4_000_000, check=baud_problem),
            Param("namespace_prefix", "/lhd", "topic prefix when the node runs in the root namespace"),
            Param("cmd_timeout", base.cmd_timeout,
                  f"s without a valid command before stop frames (at most {CMD_TIMEOUT_MAX} s)",
                  lo=0.01, hi=CMD_TIMEOUT_MAX, on_change=lambda v: self._apply(cmd_timeout=v)),
            Param("command_rate_hz", base.command_rate_hz,
                  f"command frames per second; at least 4 / device watchdog = {4.0 / wd:g} Hz (a lost frame "
                  f"must fit in half the device's {wd * 1000:.0f} ms watchdog), at most the 200 Hz watchdog tick",
                  lo=1.0, hi=1.0 / WATCHDOG_TICK, check=lambda v: command_rate_problem(v, wd),
                  on_change=lambda v: self._apply(command_rate_hz=v)),
            Param("valve_deadband", base.valve_deadband,
                  "a valve opens when |u| >= this x the joint's full speed; > 0 (0 would open it for a zero command)",
                  lo=0.0, hi=1.0, check=deadband_problem, on_change=lambda v: self._apply(valve_deadband=v)),
            Param("odom_timeout", base.odom_timeout, "s; an older machine speed is not used for drift",
                  lo=0.01, hi=10.0, on_change=lambda v: self._apply(odom_timeout=v)),
            Param("boom_zero", 0.0, "rad, the boom angle the device reports in the attack pose; subtracted from every "
                  "reading (docs/real_machine.md Calibration, step 7: both 2 deg off cost the machine's RLD 28 % of "
                  "its attempts); |zero| <= 0.35 rad", check=arm_zero_problem, on_change=lambda v: self._set_zero(0, v),
                  warn_change=ARM_ZERO_WARNING),
            Param("bucket_zero", 0.0, "rad, the bucket angle the device reports in the attack pose; subtracted from "
                  "every reading; |zero| <= 0.35 rad", check=arm_zero_problem, on_change=lambda v: self._set_zero(1, v),
                  warn_change=ARM_ZERO_WARNING),
        ])
        pv = self.params
        self.p = dataclasses.replace(base, cmd_timeout=pv["cmd_timeout"], command_rate_hz=pv["command_rate_hz"],
                                     valve_deadband=pv["valve_deadband"], odom_timeout=pv["odom_timeout"])
        self.port = pv["port"]
        self.baud = pv["baud"]
        self.arm_zeros = (float(pv["boom_zero"]), float(pv["bucket_zero"]))
        ns = topic_prefix(self, pv["namespace_prefix"])
        self.mapper = CommandMapper(self.p)
        self.watchdog = Watchdog(self.p.cmd_timeout)
        # one for the node's life: counters survive reconnects
        self.parser = FrameParser(accept={TYPE_SENSOR, TYPE_LOAD_CELL})
        self.load_cell = LoadCellMonitor()
        self.wheels = WheelAngles()      # wheel angles integrated from the reported speeds (no NaN on the topic)
        self._load_cell_said = None      # the last load-cell problem logged (logged once per change)
        self._tx = TxSequence()
        self._ser: serial.Serial | None = None
        self._ser_lock = threading.Lock()
        self._cmd: CommandFrame | None = None
        self._odom_arrival: float | None = None   # monotonic arrival time of the newest usable odometry
        self.drift_window = DriftWindow(self.p.control_period)   # the training's drift rule (bridge_core)
        self.device_clock = DeviceClock()        # each sensor frame's measurement instant on the ROS clock
        self._drift_lock = threading.Lock()      # odometry (executor) and frames (reader thread) feed it
        # the device's hold, the reset hold and the fresh-start wait: set by the reader thread, cleared by a command
        # in the executor; one lock, so a zero command taken just as a hold begins cannot clear the new wait
        self._hold_lock = threading.Lock()
        self.drift_from = "currents: no odometry yet"   # what decided the last frame's drift flags (diagnostics)
        self._unaligned_since: float | None = None      # fresh odometry, but no window over it since then
        self._device: tuple[SensorFrame, float] | None = None  # (latest sensor frame, arrival time)
        self._estop = False
        self._hold = False                 # the device holds the machine (e-stop, held, sensor fault)
        self._reset_hold_until = -math.inf
        # after a reconnection, a hold or a reset: stop frames until an all-zero command arrives (a fresh start)
        self.await_zero, self.await_zero_why = True, "the bridge started"
        self.device_resets = 0             # device resets seen while this node ran (DEVICE_RESET_HOLD_S)
        self.frame_faults = 0              # frames whose handling raised (a bug): in /diagnostics
        self._stop_evt = threading.Event()
        self.connected = False
        self.link_problem = "not opened yet"
        self.reconnects = 0
        self.disconnects = 0
        self.sensor_frames = 0
        self.command_frames = 0
        self._rate_marks = (time.monotonic(), 0, 0)
        self._error_marks: dict[str, int] = {}
        self.latency_hook = None  # for the benchmark: called with the SensorFrame after publishing
        self.pub_js = self.create_publisher(JointState, f"{ns}/joint_states", MEASUREMENT_QOS)
        self.pub_drift = self.create_publisher(Bool, f"{ns}/wheel_drift", MEASUREMENT_QOS)
        self.pub_front = self.create_publisher(Bool, f"{ns}/wheel_drift/front", MEASUREMENT_QOS)
        self.pub_rear = self.create_publisher(Bool, f"{ns}/wheel_drift/rear", MEASUREMENT_QOS)
        self.pub_status = self.create_publisher(DiagnosticStatus, f"{ns}/hw/status", MEASUREMENT_QOS)
        self.pub_mass = self.create_publisher(Float64, f"{ns}/load_cell/mass", MEASUREMENT_QOS)
        self.create_subscription(Float64MultiArray, f"{ns}/cmd", self._on_cmd, COMMAND_QOS)
        self.create_subscription(Odometry, f"{ns}/odom", self._on_odom, qos_profile_sensor_data)
        # every timer on the steady clock: with use_sim_time and no /clock they must still run.
        # The watchdog is checked every WATCHDOG_TICK s and a stop leaves at once when it trips;
        # command frames themselves go out at command_rate_hz.
        self._frames = CommandScheduler(1.0 / self.p.command_rate_hz, MIN_FRAME_GAP, time.monotonic())
        steady_timer(self, WATCHDOG_TICK, self._tick)
        steady_timer(self, 1.0, self._heartbeat)
        steady_timer(self, STATUS_PERIOD, self._publish_status)
        self.diagnostics = Diagnostics(self, {"serial link": self._link_report, "device": self._device_report,
                                              "load_cell": self._load_cell_report}, hardware_id=self.port)
        self._io = threading.Thread(target=self._io_loop, name="serial-io", daemon=True)
        self._io.start()

    def _apply(self, **changes) -> None:
        """A parameter changed at run time: every user of it sees the new value from now on."""
        self.p = dataclasses.replace(self.p, **changes)
        self.mapper.p = self.p
        self.watchdog.timeout = self.p.cmd_timeout
        self._frames.period = 1.0 / self.p.command_rate_hz

    def _set_zero(self, i: int, v: float) -> None:
        z = list(self.arm_zeros)
        z[i] = float(v)
        self.arm_zeros = (z[0], z[1])       # one assignment: the reader thread sees the old pair or the new

    # ------------------------------------------------------------------ ROS inputs
    def _on_cmd(self, msg: Float64MultiArray) -> None:
        # the fresh start is a command of exact zeros as sent (the mux's, a released trigger's, the policy node's),
        # not one the mapper turns into no motion (a review: [-1, 0.191, -0.2], all refused, counted as one)
        raw_zero = len(msg.data) == 3 and all(v == 0.0 for v in msg.data)
        try:
            frame = self.mapper.map(msg.data)
        except CommandRejected as exc:
            # a bad command is a fault of the sender: the machine stops at once (as the command mux
            # does), not at the watchdog 0.3 s later on the last valid command; the next valid
            # command moves it again
            self.get_logger().warn(f"rejected command: {exc}; stopping the machine", throttle_duration_sec=1.0)
            self._cmd = None
            self._send_command(time.monotonic(), CommandFrame.stop(), tripped=True)
            return
        self._cmd = frame
        now = time.monotonic()
        with self._hold_lock:
            fresh = self.await_zero and raw_zero and not self._hold and now >= self._reset_hold_until
            if fresh:
                self.await_zero = False    # the fresh start: commands after this one move the machine
        if fresh:
            self.get_logger().info(f"all-zero command after {self.await_zero_why}: commands move the machine again")
        self.watchdog.feed(now)
        self._send_command(now, self.current_command(now), tripped=False)   # a changed one leaves at once

    def _on_odom(self, msg: Odometry) -> None:
        """The machine's speed at the image's instant (its stamp; an unstamped message: its arrival) for
        the drift window; a non-finite speed or a repeated stamp is not used."""
        st = msg.header.stamp
        t = st.sec + st.nanosec * 1e-9 if (st.sec or st.nanosec) else self.get_clock().now().nanoseconds * 1e-9
        with self._drift_lock:
            if self.drift_window.add_odom(t, msg.twist.twist.linear.x):
                self._odom_arrival = time.monotonic()

    # ------------------------------------------------------------------ output to the device
    def _write(self, msg) -> bool:
        with self._ser_lock:
            ser = self._ser
            if ser is None:
                return False
            try:
                ser.write(self._tx.encode(msg))
                return True
            except (serial.SerialException, OSError) as exc:
                self.get_logger().warn(f"serial write failed: {exc}", throttle_duration_sec=1.0)
                self.link_problem = f"write to {self.port} failed: {exc}"
                self._drop_port_locked()
                return False

    def current_command(self, now: float) -> CommandFrame:
        stale = self.watchdog.stale(now)
        if stale or self._hold or self._cmd is None or self.device_silent(now) or now < self._reset_hold_until \
                or self.await_zero:
            return CommandFrame.stop()
        return self._cmd

    def device_silent(self, now: float) -> bool:
        """No sensor frame for cmd_timeout (or none yet): the device's state is unknown (a frozen
        firmware, a cable that carries our frames but not its), so it is sent stops, not motion."""
        return self._device is None or now - self._device[1] > self.p.cmd_timeout

    def _tick(self) -> None:
        now = time.monotonic()
        if self._device is not None and now - self._device[1] > SILENCE_FRESH_START_S and not self.await_zero:
            # frames stopped long enough for an e-stop to be pressed and released unseen (a cable that carries ours
            # but not the device's), while the stop frames sent meanwhile clear the device's hold (a review,
            # 2026-11-30). Shorter gaps (a busy host) get stop frames (device_silent) but no fresh start
            with self._hold_lock:
                self._need_zero(f"a silence of the device ({now - self._device[1]:.1f} s without a sensor frame)")
            self.get_logger().warn(f"{self.await_zero_why}: machine held stopped until an all-zero command")
        trips = self.watchdog.trips
        cmd = self.current_command(now)         # checks the watchdog: a trip sends the stop at once
        tripped = self.watchdog.trips > trips
        if tripped:
            self.get_logger().warn(f"no valid command for {self.p.cmd_timeout} s: stopping the machine",
                                   throttle_duration_sec=1.0)
        self._send_command(now, cmd, tripped)

    def _send_command(self, now: float, cmd: CommandFrame, tripped: bool) -> None:
        if tripped or self._frames.due(now, cmd):
            self._frames.sent(now, cmd)
            if self._write(cmd):
                self.command_frames += 1

    def _heartbeat(self) -> None:
        self._write(HeartbeatFrame(int(time.monotonic() * 1000) & 0xFFFFFFFF))

    # ------------------------------------------------------------------ serial input
    def _drop_port_locked(self) -> None:
        if self._ser is not None:
            try:
                self._ser.close()
            except Exception:  # noqa: BLE001 - closing a vanished port may fail in any way
                pass
            self._ser = None
            self.connected = False
            self.disconnects += 1

    def _open(self) -> bool:
        try:
            # exclusive: flock(LOCK_EX), so two bridges (or a terminal program) never both write
            ser = serial.Serial(self.port, self.baud, timeout=0.01, write_timeout=0.1, exclusive=True)
        except (serial.SerialException, OSError, ValueError) as exc:
            self.link_problem = open_problem(self.port, exc)
            self.get_logger().warn(self.link_problem, throttle_duration_sec=10.0)
            return False
        with self._ser_lock:
            self._ser = ser
            self.parser.reset_link()
            # the first frame on a (re)opened link is a stop; older commands no longer count. A 0x00
            # first ends whatever partial frame the device still holds (a write cut short by the
            # unplug): glued to it, the stop would fail its CRC (a review, 2026-11-30)
            self.watchdog.rearm(time.monotonic())
            with self._hold_lock:
                self._need_zero("a reconnection of the serial link")
            try:
                ser.write(b"\x00" + self._tx.encode(CommandFrame.stop()))
            except (serial.SerialException, OSError) as exc:
                self.link_problem = f"write to {self.port} failed: {exc}"
                self._drop_port_locked()
                return False
            self.connected = True
        return True

    def _io_loop(self) -> None:
        backoff = self.p.backoff_min
        first = True
        while not self._stop_evt.is_set():
            if self._ser is None:
                if self._open():
                    if not first:
                        self.reconnects += 1
                    self.get_logger().info(f"serial link up on {self.port}")
                    first = False
                    backoff = self.p.backoff_min
                else:
                    self._stop_evt.wait(backoff)
                    backoff = min(backoff * 2.0, self.p.backoff_max)
                continue
            ser = self._ser
            try:
                data = ser.read(max(1, ser.in_waiting))
            except (serial.SerialException, OSError, TypeError) as exc:
                with self._ser_lock:
                    closed_by_writer = self._ser is not ser
                    if not closed_by_writer:
                        self._drop_port_locked()
                if closed_by_writer:
                    # the writer dropped the port after a failed write (its problem stands); reading
                    # the closed port gave a TypeError that said nothing about the link (a review)
                    continue
                self.get_logger().warn(f"serial link lost on {self.port}: {exc}", throttle_duration_sec=1.0)
                self.link_problem = f"serial link lost on {self.port}: {exc}"
                continue
            if data:
                for _, msg in self.parser.feed(data):   # sensor and load-cell frames only (accept)
                    try:
                        if isinstance(msg, LoadCellFrame):
                            self._on_load_cell(msg)
                        else:
                            self._publish(msg)
                    except Exception as exc:  # noqa: BLE001 - a fault here must not end the reader thread in silence
                        # (the device's state would go stale and stop frames follow, but nobody would know why)
                        self.frame_faults += 1
                        self.get_logger().error(f"handling a frame from the device failed: {exc!r}",
                                                throttle_duration_sec=1.0)

    def _publish(self, f: SensorFrame) -> None:
        now = time.monotonic()
        self.sensor_frames += 1
        if not f.flags & FLAG_SENSOR_FAULT:
            # a frame with a sensor fault carries no reading (an angle, rate, wheel speed or current that is not
            # one): no joint state, no drift flag, nothing integrated from it (a review, 2026-11-30)
            self._publish_measurements(f, now)
        self._device_state(f, now)

    def _publish_measurements(self, f: SensorFrame, now: float) -> None:
        js = JointState()
        stamp = self.get_clock().now()
        t_frame = self.device_clock.stamp(f.device_time_us, stamp.nanoseconds * 1e-9)   # measured, not arrived
        # the frame's measurement instant, as /lhd/odom carries its image's and the slope its scan's: a burst
        # of frames held up by USB or a busy host (read at once) keeps the 10 ms between them instead of
        # sharing the burst's arrival (a review, 2026-11-29: 25 frames over 0.24 s stamped within 3 ms).
        # Never after the arrival (DeviceClock takes the least delay), and non-decreasing
        js.header.stamp = Time(nanoseconds=int(round(t_frame * 1e9)), clock_type=stamp.clock_type).to_msg()
        js.name = list(JOINT_NAMES)
        js.position, js.velocity = joint_state_arrays(f, self.wheels, self.arm_zeros)
        self.pub_js.publish(js)
        a = self.wheels.angles
        with self._drift_lock:
            self.drift_window.add_wheels(t_frame, (a[0], a[1], 0.5 * (a[2] + a[3])), self.wheels.restarts)
            fresh = self._odom_arrival is not None and now - self._odom_arrival <= self.p.odom_timeout
            slip = self.drift_window.slips(self.p) if fresh else None
            reason = self.drift_window.reason
        if slip is not None:
            self.drift_from, self._unaligned_since = "travel", None
        elif not fresh:
            self.drift_from, self._unaligned_since = f"currents: no odometry for {self.p.odom_timeout:g} s", None
        else:
            self.drift_from = f"currents: {reason}"      # fresh odometry, no window: named in /diagnostics after 1 s
            self._unaligned_since = now if self._unaligned_since is None else self._unaligned_since
        front, rear = detect_drift(f, slip, self.p)
        self.pub_front.publish(Bool(data=front))
        self.pub_rear.publish(Bool(data=rear))
        self.pub_drift.publish(Bool(data=front or rear))
        if self.latency_hook is not None:
            self.latency_hook(f)

    def _device_state(self, f: SensorFrame, now: float) -> None:
        prev = self._device[0] if self._device is not None else None
        self._device = (f, now)
        # the device holds the machine (its e-stop, a sensor fault, or held after a reset until a stop
        # frame): stop frames meanwhile, and then an all-zero command before motion
        hold = bool(f.flags & (FLAG_ESTOP | FLAG_HELD | FLAG_SENSOR_FAULT))
        with self._hold_lock:
            self._hold_update(f, prev, hold, now)
        self._estop = bool(f.flags & FLAG_ESTOP)
        if prev is None or (prev.flags, prev.valve_boom, prev.valve_bucket) != (f.flags, f.valve_boom, f.valve_bucket):
            self._publish_status()

    def _hold_update(self, f: SensorFrame, prev: SensorFrame | None, hold: bool, now: float) -> None:
        """The hold, reset hold and fresh-start wait from this frame (under _hold_lock)."""
        if f.flags & FLAG_RESET and prev is not None and not prev.flags & FLAG_RESET:
            # the device was reset (power, brown-out, its watchdog) while this node ran: ERROR and stop frames
            # for DEVICE_RESET_HOLD_S, so the supervisor ends a running attempt, though the first stop frame
            # clears the device's hold at once. (Seen at power-up, before this node's first stop: not a reset
            # during a run. A reset on the native USB port drops the link first: a reconnection, below.)
            self.device_resets += 1
            self._reset_hold_until = now + DEVICE_RESET_HOLD_S
            self.get_logger().error("the device was reset: machine held stopped, stop frames sent; it moves again "
                                    "after an all-zero command")
            self._need_zero("a reset of the device")
        if hold and not self._hold:
            self._need_zero("the device held the machine (e-stop, sensor fault or held)")
        if self._hold and not hold:
            self.watchdog.rearm(now)   # released: only commands received from now on count
        self._hold = hold

    def _need_zero(self, why: str) -> None:
        """Stop frames until an all-zero command, for the latest reason (called under _hold_lock)."""
        self.await_zero, self.await_zero_why = True, why

    def _on_load_cell(self, f: LoadCellFrame) -> None:
        mass = self.load_cell.accept(f, time.monotonic())
        if mass is not None:
            self.pub_mass.publish(Float64(data=mass))
            self._load_cell_said = None
            return
        said = tuple(self.load_cell.problems)
        if said != self._load_cell_said:     # once per change of reason, not at 10 Hz
            self._load_cell_said = said
            self.get_logger().warn("load cell: mass not published: " + "; ".join(said))

    # ------------------------------------------------------------------ status and diagnostics
    def _load_cell_report(self):
        level, message, values = self.load_cell.report(time.monotonic())
        return LEVELS[level], message, values

    def _device_report(self):
        """(level, message, values) of the device: its flags, motor currents and valve states."""
        dev = self._device
        if dev is None:
            return STALE, "no sensor frame from the device yet", {}
        f, t = dev
        age = time.monotonic() - t
        values = {"flags": f.flags, "drive_enabled": bool(f.flags & FLAG_ENABLED),
                  "device_watchdog_stop": bool(f.flags & FLAG_WATCHDOG), "estop": bool(f.flags & FLAG_ESTOP),
                  "current_fl_A": round(f.current_fl, 3), "current_fr_A": round(f.current_fr, 3),
                  "current_rear_A": round(f.current_rear, 3), "valve_boom": f.valve_boom,
                  "valve_bucket": f.valve_bucket, "device_time_us": f.device_time_us, "age_s": round(age, 3),
                  # the device's own arm angles (before the zeros) and the zeros: what the calibration reads
                  "boom_angle_device_rad": round(f.boom_angle, 4), "bucket_angle_device_rad": round(f.bucket_angle, 4),
                  "boom_zero_rad": self.arm_zeros[0], "bucket_zero_rad": self.arm_zeros[1],
                  # this node's own watchdog timed out: no valid command for cmd_timeout, stop frames
                  # sent (the supervisor ends a running attempt on it). Not Watchdog.stale: that also
                  # covers the wait for a first command after a reconnection, and counts trips
                  "command_stale": self.watchdog.timed_out(time.monotonic())}
        values["device_held"] = bool(f.flags & FLAG_HELD)
        values["arm_sensor_fault"] = bool(f.flags & FLAG_SENSOR_FAULT)
        values["device_resets"] = self.device_resets
        values["awaiting_zero_command"] = self.await_zero
        if f.flags & FLAG_SENSOR_FAULT:       # the frame's readings are not readings: none shown as one
            for k in ("current_fl_A", "current_fr_A", "current_rear_A", "boom_angle_device_rad",
                      "bucket_angle_device_rad"):
                values[k] = "invalid (sensor fault)"
        if age > DEVICE_STALE:
            return STALE, f"no sensor frame from the device for {age:.1f} s", values
        if f.flags & FLAG_ESTOP:
            return ERROR, "emergency stop pressed on the device: machine held stopped, stop frames sent", values
        if f.flags & FLAG_SENSOR_FAULT:
            return (ERROR, "sensor fault on the device (an arm angle NaN or beyond its joint's limits by 0.3 rad: a "
                           "broken wire, a failed conversion; or a NaN wheel speed or current): machine held stopped, "
                           "no joint state or drift flag published", values)
        if time.monotonic() < self._reset_hold_until:
            return (ERROR, f"the device was reset (power, brown-out, its watchdog): machine held stopped for "
                           f"{DEVICE_RESET_HOLD_S:g} s, stop frames sent; then it moves again after an all-zero "
                           "command", values)
        if f.flags & FLAG_HELD:
            return WARN, "device holds the machine stopped until a stop frame (power-up, released e-stop)", values
        if self.await_zero and self._cmd is not None and not zero_motion(self._cmd):
            # ERROR: a command asks for motion that is withheld, so a running attempt ends (lost_input) instead of
            # standing still to its timeout and counting (a review, 2026-11-30: a 0.1 s USB stall did that)
            return (ERROR, f"machine held stopped after {self.await_zero_why}: a command asks for motion; it moves "
                           "again after an all-zero command on <prefix>/cmd (release the gamepad's trigger; a running "
                           "attempt ends)", values)
        if f.flags & FLAG_WATCHDOG:
            return (WARN, f"device watchdog holds the machine stopped (no command frame for "
                          f"{self.p.device_watchdog * 1000:.0f} ms); cleared by the next command", values)
        return OK, "drive enabled" if f.flags & FLAG_ENABLED else "drive disabled (stop commanded)", values

    def _publish_status(self) -> None:
        level, message, values = self._device_report()
        self.pub_status.publish(status(f"{self.get_fully_qualified_name()}: device", self.port, level, message,
                                       values))

    def _link_report(self):
        now = time.monotonic()
        t0, s0, c0 = self._rate_marks
        dt = max(now - t0, 1e-6)
        sensor_hz, command_hz = (self.sensor_frames - s0) / dt, (self.command_frames - c0) / dt
        self._rate_marks = (now, self.sensor_frames, self.command_frames)
        stale = self.watchdog.stale(now)
        values = {"port": self.port, "connected": self.connected, "sensor_frame_rate_hz": round(sensor_hz, 1),
                  "command_frame_rate_hz": round(command_hz, 1), **self.parser.counters(),
                  "watchdog_trips": self.watchdog.trips, "rejected_commands": self.mapper.rejected,
                  "clamped_commands": self.mapper.clamped, "reconnects": self.reconnects,
                  "disconnects": self.disconnects, "command_stale": stale, "drift_from": self.drift_from,
                  "frame_handling_faults": self.frame_faults}
        errors = {k: values[k] for k in ("framing_errors", "crc_errors", "overflows", "unknown_types")}
        new_errors = {k: v - self._error_marks.get(k, 0) for k, v in errors.items()}
        self._error_marks = errors
        if not self.connected:
            return ERROR, f"serial link down: {self.link_problem}", values
        if self.frame_faults:
            return ERROR, (f"{self.frame_faults} device frame(s) could not be handled (a fault of this node: see its "
                           "log); stop frames follow when sensor frames stop being taken"), values
        if sensor_hz < 50.0:
            if sum(new_errors.values()) and sensor_hz < 1.0:
                said = ", ".join(f"{v} {k.replace('_', ' ')}" for k, v in new_errors.items() if v)
                why = (f"bytes arrive on {self.port} but make no valid frame ({said} in {dt:.1f} s): wrong baud rate "
                       f"({self.baud}), wrong port, or not the LHD firmware? Stop frames sent")
                self.get_logger().error(why, throttle_duration_sec=10.0)
                return ERROR, why, values
            return WARN, (f"sensor frames at {sensor_hz:.0f} Hz (< 50 Hz)"
                          f"{': stop frames sent' if self.device_silent(now) else ''}"), values
        if stale:
            return WARN, "no valid command: machine stopped", values
        if self._unaligned_since is not None and now - self._unaligned_since > 1.0:
            # odometry arrives but gives no window for a second: its stamps on another clock (use_sim_time on
            # one side, a camera driver's own time base) or far late, so the drift flags fall back on the currents
            return WARN, (f"drift from the motor currents only: {self.drift_from}; expected /lhd/odom stamped "
                          "with the image's instant on this node's clock, at most "
                          f"{self.drift_window.max_age:g} s before the newest sensor frame"), values
        return OK, "ok", values

    def shutdown(self) -> None:
        """Stop the machine, then close the port."""
        self._stop_evt.set()
        self._write(CommandFrame.stop())
        self._io.join(timeout=1.0)
        with self._ser_lock:
            self._drop_port_locked()


def main(args=None) -> int:
    return run_node(BridgeNode, "lhd_hw_bridge", args, before_destroy=lambda n: n.shutdown())


if __name__ == "__main__":
    raise SystemExit(main())
