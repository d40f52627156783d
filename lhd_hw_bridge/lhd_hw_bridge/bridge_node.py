"""`ros2 run lhd_hw_bridge bridge_node`: the LHD's Arduino Due over a serial link.

Publishes what the sim node publishes (same names, SI units): /lhd/joint_states,
/lhd/wheel_drift, /lhd/wheel_drift/front, /lhd/wheel_drift/rear, plus /diagnostics.
Subscribes /lhd/cmd ([u_wheels, u_boom, u_bucket] rad/s) and /lhd/odom (machine speed for
drift detection; on hardware it comes from the ArUco node).

Fail-safe behaviour:
* every command goes through CommandMapper (no reverse wheels, no boom lowering, no bucket
  forward tilt; NaN / wrong length rejected and counted);
* no valid /lhd/cmd for cmd_timeout (0.3 s) -> stop frames (watchdog, on arrival time);
* serial loss -> reopen with exponential backoff inside the node; the first frame after a
  reconnection is a stop, and only commands received after it count;
* on shutdown a stop frame is sent before the port closes.
"""
from __future__ import annotations

import math
import threading
import time

import serial
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64MultiArray

from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.ros.qos import COMMAND_QOS, MEASUREMENT_QOS
from lhd_loading_ros.ros.run import number_param, run_node

from .bridge_core import JOINT_NAMES, BridgeParams, CommandMapper, CommandRejected, Watchdog, detect_drift, joint_state_arrays
from .protocol import CommandFrame, FrameParser, HeartbeatFrame, SensorFrame, encode

# QoS (lhd_loading_ros.ros.qos): measurements MEASUREMENT_QOS (reliable, keep-last 5: matches
# reliable and best-effort subscribers; a short queue never delays fresh data behind stale
# data), commands COMMAND_QOS (reliable, keep-last 1: only the newest command matters, and
# losing it silently would let the watchdog stop the machine). Odometry in: sensor-data QoS
# (best effort), which accepts any publisher.
WATCHDOG_TICK = 0.005  # s


class BridgeNode(Node):
    def __init__(self, cfg: dict | None = None, **node_kwargs):
        super().__init__("lhd_hw_bridge", **node_kwargs)
        self.declare_parameter("port", "/dev/ttyACM0")
        self.declare_parameter("baud", 115200)
        self.declare_parameter("config", "")
        cfg_path = self.get_parameter("config").value or None
        cfg = cfg if cfg is not None else load_config(cfg_path)
        base = BridgeParams.from_config(cfg)
        self.declare_parameter("cmd_timeout", base.cmd_timeout)
        self.declare_parameter("command_rate_hz", base.command_rate_hz)
        self.declare_parameter("valve_deadband", base.valve_deadband)
        self.declare_parameter("odom_timeout", base.odom_timeout)
        self.declare_parameter("namespace_prefix", "/lhd")
        gp = lambda n: self.get_parameter(n).value  # noqa: E731
        number_param(self, "cmd_timeout", 0.01, 10.0)
        number_param(self, "command_rate_hz", 1.0, 1000.0)
        number_param(self, "valve_deadband", 0.0, 1.0)
        number_param(self, "odom_timeout", 0.01, 10.0)
        self.p = BridgeParams(**{**base.__dict__, "cmd_timeout": float(gp("cmd_timeout")),
                                 "command_rate_hz": float(gp("command_rate_hz")),
                                 "valve_deadband": float(gp("valve_deadband")), "odom_timeout": float(gp("odom_timeout"))})
        self.port = gp("port")
        self.baud = int(gp("baud"))
        ns = gp("namespace_prefix").rstrip("/")
        self.mapper = CommandMapper(self.p)
        self.watchdog = Watchdog(self.p.cmd_timeout)
        self.parser = FrameParser()
        self._ser: serial.Serial | None = None
        self._ser_lock = threading.Lock()
        self._seq = 0
        self._cmd: CommandFrame | None = None
        self._v_machine: tuple[float, float] | None = None  # (speed, arrival time)
        self._stop_evt = threading.Event()
        self.connected = False
        self.reconnects = 0
        self.disconnects = 0
        self.sensor_frames = 0
        self.command_frames = 0
        self._rate_marks = (time.monotonic(), 0, 0)
        self._rates = (0.0, 0.0)
        self.latency_hook = None  # for the benchmark: called with the SensorFrame after publishing
        self.pub_js = self.create_publisher(JointState, f"{ns}/joint_states", MEASUREMENT_QOS)
        self.pub_drift = self.create_publisher(Bool, f"{ns}/wheel_drift", MEASUREMENT_QOS)
        self.pub_front = self.create_publisher(Bool, f"{ns}/wheel_drift/front", MEASUREMENT_QOS)
        self.pub_rear = self.create_publisher(Bool, f"{ns}/wheel_drift/rear", MEASUREMENT_QOS)
        self.pub_diag = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_subscription(Float64MultiArray, f"{ns}/cmd", self._on_cmd, COMMAND_QOS)
        self.create_subscription(Odometry, f"{ns}/odom", self._on_odom, qos_profile_sensor_data)
        # the watchdog is checked every WATCHDOG_TICK s and a stop leaves at once when it trips;
        # command frames themselves go out at command_rate_hz
        self._frame_every = max(1, int(round(1.0 / (self.p.command_rate_hz * WATCHDOG_TICK))))
        self._ticks = 0
        self.create_timer(WATCHDOG_TICK, self._tick)
        self.create_timer(1.0, self._diagnostics)
        self.create_timer(1.0, self._heartbeat)
        self._io = threading.Thread(target=self._io_loop, name="serial-io", daemon=True)
        self._io.start()

    # ------------------------------------------------------------------ ROS inputs
    def _on_cmd(self, msg: Float64MultiArray) -> None:
        try:
            frame = self.mapper.map(msg.data)
        except CommandRejected as exc:
            self.get_logger().warn(f"rejected command: {exc}", throttle_duration_sec=1.0)
            return
        self._cmd = frame
        self.watchdog.feed(time.monotonic())

    def _on_odom(self, msg: Odometry) -> None:
        v = msg.twist.twist.linear.x
        if math.isfinite(v):
            self._v_machine = (v, time.monotonic())

    # ------------------------------------------------------------------ output to the device
    def _write(self, msg) -> bool:
        with self._ser_lock:
            ser = self._ser
            if ser is None:
                return False
            try:
                ser.write(encode(msg, self._seq))
                self._seq = (self._seq + 1) & 0xFF
                return True
            except (serial.SerialException, OSError) as exc:
                self.get_logger().warn(f"serial write failed: {exc}", throttle_duration_sec=1.0)
                self._drop_port_locked()
                return False

    def current_command(self, now: float) -> CommandFrame:
        if self.watchdog.stale(now) or self._cmd is None:
            return CommandFrame.stop()
        return self._cmd

    def _tick(self) -> None:
        now = time.monotonic()
        trips = self.watchdog.trips
        cmd = self.current_command(now)
        tripped = self.watchdog.trips > trips
        if tripped:
            self.get_logger().warn(f"no valid /lhd/cmd for {self.p.cmd_timeout} s: stopping the machine",
                                   throttle_duration_sec=1.0)
        self._ticks += 1
        if tripped or self._ticks >= self._frame_every:
            self._ticks = 0
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
            ser = serial.Serial(self.port, self.baud, timeout=0.01, write_timeout=0.1)
        except (serial.SerialException, OSError, ValueError):
            return False
        with self._ser_lock:
            self._ser = ser
            self.parser = FrameParser()
            # the first frame on a (re)opened link is a stop; older commands no longer count
            self.watchdog.rearm(time.monotonic())
            try:
                ser.write(encode(CommandFrame.stop(), self._seq))
                self._seq = (self._seq + 1) & 0xFF
            except (serial.SerialException, OSError):
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
                self.get_logger().warn(f"serial link lost on {self.port}: {exc}", throttle_duration_sec=1.0)
                with self._ser_lock:
                    if self._ser is ser:
                        self._drop_port_locked()
                continue
            if data:
                for _, msg in self.parser.feed(data):
                    if isinstance(msg, SensorFrame):
                        self._publish(msg)

    def _publish(self, f: SensorFrame) -> None:
        now = time.monotonic()
        self.sensor_frames += 1
        js = JointState()
        js.header.stamp = self.get_clock().now().to_msg()
        js.name = list(JOINT_NAMES)
        js.position, js.velocity = joint_state_arrays(f)
        self.pub_js.publish(js)
        v = None
        if self._v_machine is not None and now - self._v_machine[1] <= self.p.odom_timeout:
            v = self._v_machine[0]
        front, rear = detect_drift(f, v, self.p)
        self.pub_front.publish(Bool(data=front))
        self.pub_rear.publish(Bool(data=rear))
        self.pub_drift.publish(Bool(data=front or rear))
        if self.latency_hook is not None:
            self.latency_hook(f)

    # ------------------------------------------------------------------ diagnostics
    def _diagnostics(self) -> None:
        now = time.monotonic()
        t0, s0, c0 = self._rate_marks
        dt = max(now - t0, 1e-6)
        self._rates = ((self.sensor_frames - s0) / dt, (self.command_frames - c0) / dt)
        self._rate_marks = (now, self.sensor_frames, self.command_frames)
        st = DiagnosticStatus()
        st.name = "lhd_hw_bridge: serial link"
        st.hardware_id = self.port
        stale = self.watchdog.stale(now)
        if not self.connected:
            st.level, st.message = DiagnosticStatus.ERROR, "serial link down"
        elif self._rates[0] < 50.0:
            st.level, st.message = DiagnosticStatus.WARN, f"sensor frames at {self._rates[0]:.0f} Hz (< 50 Hz)"
        elif stale:
            st.level, st.message = DiagnosticStatus.WARN, "no valid command: machine stopped"
        else:
            st.level, st.message = DiagnosticStatus.OK, "ok"
        vals = {
            "port": self.port, "connected": self.connected, "sensor_frame_rate_hz": round(self._rates[0], 1),
            "command_frame_rate_hz": round(self._rates[1], 1), "crc_errors": self.parser.crc_errors,
            "framing_errors": self.parser.framing_errors, "overflows": self.parser.overflows,
            "sequence_gaps": self.parser.seq_gaps, "watchdog_trips": self.watchdog.trips,
            "rejected_commands": self.mapper.rejected, "clamped_commands": self.mapper.clamped,
            "reconnects": self.reconnects, "disconnects": self.disconnects, "command_stale": stale,
        }
        st.values = [KeyValue(key=k, value=str(v)) for k, v in vals.items()]
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status = [st]
        self.pub_diag.publish(arr)

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
