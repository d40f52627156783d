"""`ros2 run lhd_loading_ros policy_node`: the exported actor at 10 Hz.

Every cycle it rebuilds the task state from the latest topics (forward kinematics from
/lhd/odom and /lhd/joint_states, drift flags, slope, end zone), builds the 12-vector with
the environment's own code (lhd_loading_ros.task.observation), runs the actor (numpy, no torch),
applies the variant's deployment filter, maps to rad/s and publishes /lhd/cmd and
/lhd/observation. An input older than input_timeout, a NaN, or no loaded actor gives the
zero command (wheels stopped, arm held) and a throttled warning. When /lhd/episode reports
the end of an episode it sends one zero command and stops commanding until the next one.

trigger = timer     10 Hz on the node's clock (the real machine; sim node in realtime mode)
trigger = lockstep  one decision per state of the sim node in lockstep mode: when
                    /lhd/joint_states, /lhd/odom and /lhd/episode carry the same stamp
"""
from __future__ import annotations

import math
import time
from collections import deque
from pathlib import Path

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from nav_msgs.msg import Odometry
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float32MultiArray, Float64, Float64MultiArray

from lhd_loading_ros.task.config import config_hash, load_config
from lhd_loading_ros.task.kinematics import ArmKinematics
from lhd_loading_ros.task.params import TaskParams
from lhd_loading_ros.policy.core import Inputs, PolicyCore, ZERO_COMMAND
from lhd_loading_ros.policy.actor_file import PolicyFileError, load_policy
from lhd_loading_ros.ros.qos import COMMAND_QOS, MEASUREMENT_QOS, STATUS_QOS
from lhd_loading_ros.ros.run import number_param, run_node

# QoS (lhd_loading_ros.ros.qos). Inputs: `input_qos` = sensor_data (best effort) matches every
# publisher, reliable or not (the ArUco node publishes odometry best effort); `reliable`
# (MEASUREMENT_QOS) is for lockstep runs, where a lost state would stall the loop. Commands
# out: COMMAND_QOS. Observation out: MEASUREMENT_QOS. Episode status in: STATUS_QOS.
TRIGGERS = ("timer", "lockstep")


def default_policy_dir(variant: str = "rld") -> Path:
    """policies/<variant> of the source tree, else the installed share copy."""
    here = Path(__file__).resolve()
    for parent in here.parents:
        cand = parent / "policies" / variant
        if (cand / "policy.json").is_file():
            return cand
    try:
        from ament_index_python.packages import get_package_share_directory

        return Path(get_package_share_directory("lhd_loading_ros")) / "policies" / variant
    except Exception:  # noqa: BLE001 - no ament index here
        return Path("policies") / variant


def stamp_ns(stamp) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


class PolicyNode(Node):
    def __init__(self, **node_kwargs):
        super().__init__("lhd_policy", **node_kwargs)
        self.declare_parameter("config", "")
        cfg = load_config(self.get_parameter("config").value or None)
        p = TaskParams.from_config(cfg)
        self.declare_parameter("policy_dir", "")
        self.declare_parameter("rate_hz", float(cfg["paper"]["control"]["frequency_hz"]))
        self.declare_parameter("input_timeout", 0.5)
        self.declare_parameter("trigger", "timer")
        self.declare_parameter("input_qos", "sensor_data")
        self.declare_parameter("namespace_prefix", "/lhd")
        gp = lambda n: self.get_parameter(n).value  # noqa: E731
        self.rate_hz = number_param(self, "rate_hz", 0.1, 1000.0)
        self.input_timeout = number_param(self, "input_timeout", 0.01, 60.0)
        self.trigger = gp("trigger")
        if self.trigger not in TRIGGERS:
            raise ValueError(f"parameter 'trigger' = {self.trigger!r} is invalid; expected one of {TRIGGERS}")
        qos_name = gp("input_qos")
        if qos_name not in ("sensor_data", "reliable"):
            raise ValueError(f"parameter 'input_qos' = {qos_name!r} is invalid; expected 'sensor_data' or 'reliable'")
        qin = qos_profile_sensor_data if qos_name == "sensor_data" else MEASUREMENT_QOS
        ns = gp("namespace_prefix").rstrip("/")

        path = gp("policy_dir") or str(default_policy_dir("rld"))
        actor, variant = None, "rld"
        try:
            pol = load_policy(path)
            actor, variant = pol.actor, pol.variant
            if pol.meta.get("config_hash") not in (None, "") and pol.meta["config_hash"] != config_hash(cfg):
                self.get_logger().warn(f"policy {path} was trained with another parameter file "
                                       f"(config hash {pol.meta['config_hash']}); check the filters and ranges")
            self.get_logger().info(f"loaded {variant.upper()} actor from {path} (sizes {pol.actor.sizes})")
        except PolicyFileError as exc:
            self.get_logger().error(f"no actor: {exc}. Publishing zero commands.")
        self.core = PolicyCore(actor, variant, p, ArmKinematics.from_config(cfg))
        self.policy_path = path
        self.inputs = Inputs()
        self.episode_state = None        # None: no /lhd/episode publisher (hardware): always running
        self.episode_key = None
        self._status_stamp = None
        self._stopped_key = None
        self._stamps = {"joints": None, "odom": None}
        self._decided_stamp = None
        self.cycles = 0
        self.zero_cycles = 0
        self.latencies_ms: deque = deque(maxlen=100_000)
        self.periods_ms: deque = deque(maxlen=100_000)
        self._last_tick = None

        self.pub_cmd = self.create_publisher(Float64MultiArray, f"{ns}/cmd", COMMAND_QOS)
        self.pub_obs = self.create_publisher(Float32MultiArray, f"{ns}/observation", MEASUREMENT_QOS)
        self.pub_diag = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_subscription(JointState, f"{ns}/joint_states", self._on_js, qin)
        self.create_subscription(Odometry, f"{ns}/odom", self._on_odom, qin)
        self.create_subscription(Bool, f"{ns}/wheel_drift/front", lambda m: self._put("drift_front", bool(m.data)), qin)
        self.create_subscription(Bool, f"{ns}/wheel_drift/rear", lambda m: self._put("drift_rear", bool(m.data)), qin)
        self.create_subscription(Float64, f"{ns}/pile/slope", self._on_slope, qin)
        self.create_subscription(Float64MultiArray, f"{ns}/pile/end_zone", self._on_zone, qin)
        self.create_subscription(DiagnosticStatus, f"{ns}/episode", self._on_status, STATUS_QOS)
        if self.trigger == "timer":
            self.create_timer(1.0 / self.rate_hz, self._on_timer)
        self.create_timer(1.0, self._diagnostics)

    # ------------------------------------------------------------------ inputs
    def _put(self, name, value) -> None:
        self.inputs.put(name, value, time.monotonic())

    def _on_js(self, msg: JointState) -> None:
        joints = {}
        for i, n in enumerate(msg.name):
            pos = msg.position[i] if i < len(msg.position) else math.nan
            vel = msg.velocity[i] if i < len(msg.velocity) else math.nan
            joints[n] = (pos, vel)
        if "boom" not in joints or "bucket" not in joints:
            self.get_logger().warn(f"joint_states without boom/bucket (got {list(msg.name)})", throttle_duration_sec=2.0)
            return
        self._put("joints", joints)
        self._stamps["joints"] = stamp_ns(msg.header.stamp)
        self._maybe_lockstep()

    def _on_odom(self, msg: Odometry) -> None:
        pp, q = msg.pose.pose.position, msg.pose.pose.orientation
        self._put("odom", ((pp.x, pp.y, pp.z), (q.w, q.x, q.y, q.z), msg.twist.twist.linear.x))
        self._stamps["odom"] = stamp_ns(msg.header.stamp)
        self._maybe_lockstep()

    def _on_slope(self, msg: Float64) -> None:
        self._put("slope", float(msg.data))

    def _on_zone(self, msg: Float64MultiArray) -> None:
        if len(msg.data) != 3:
            self.get_logger().warn(f"end_zone must be [x_min, x_max, z_min], got {list(msg.data)}",
                                   throttle_duration_sec=2.0)
            return
        self._put("end_zone", tuple(float(v) for v in msg.data))

    def _on_status(self, msg) -> None:
        kv = {k.key: k.value for k in msg.values}
        self.episode_state = kv.get("state", msg.message)
        self.episode_key = kv.get("episode")
        try:
            self._status_stamp = int(kv["stamp_ns"])
            if self.trigger == "lockstep":   # the unstamped inputs of exactly this state
                self._put("drift_front", kv["drift_front"] == "True")
                self._put("drift_rear", kv["drift_rear"] == "True")
                self._put("slope", float(kv["slope_rad"]))
                self._put("end_zone", tuple(float(v) for v in kv["end_zone"].split(",")))
        except (KeyError, ValueError):
            self._status_stamp = None
        self._maybe_lockstep()

    # ------------------------------------------------------------------ decisions
    def _maybe_lockstep(self) -> None:
        if self.trigger != "lockstep":
            return
        t = self._stamps["joints"]
        if t is None or self._stamps["odom"] != t or self._status_stamp != t or t == self._decided_stamp:
            return
        if self._cycle(lockstep=True):
            self._decided_stamp = t          # one decision per state (the sim node may repeat one)

    def _on_timer(self) -> None:
        now = time.monotonic()
        if self._last_tick is not None:
            self.periods_ms.append((now - self._last_tick) * 1000.0)
        self._last_tick = now
        self._cycle()

    def _cycle(self, lockstep: bool = False) -> bool:
        """Decide and publish; returns False when a lockstep state was left undecided (inputs
        not all received yet: the sim node repeats its state, and a zero command would step it)."""
        t0 = time.perf_counter()
        if self.episode_state is not None and self.episode_state != "running":
            key = (self.episode_key, self.episode_state)
            if self._stopped_key != key:     # episode over: one zero command, then silence
                self._stopped_key = key
                self.pub_cmd.publish(Float64MultiArray(data=list(ZERO_COMMAND)))
            return True
        # Lockstep: the decision waits for joints, odometry and the status (drift, slope, end
        # zone) of one stamp, so every input is of exactly this state however long ago one of
        # them arrived (the sim node repeats a state whose first copy went unheard, and is paused
        # meanwhile); a wall-clock age would only turn a slow start into a spurious zero command
        # that steps the simulator. Only "never received" counts there.
        timeout = math.inf if lockstep else self.input_timeout
        d = self.core.decide(self.inputs, time.monotonic(), timeout)
        if lockstep and d.reason and self.core.actor is not None and self.inputs.missing():
            self.get_logger().info(f"waiting for inputs: {d.reason}", throttle_duration_sec=2.0)
            return False
        self.pub_cmd.publish(Float64MultiArray(data=list(d.command)))
        if not d.reason:   # latency: inputs -> observation -> actor -> command published
            self.latencies_ms.append((time.perf_counter() - t0) * 1000.0)
        if d.observation is not None:   # for debugging, after the command
            self.pub_obs.publish(Float32MultiArray(data=d.observation.tolist()))
        self.cycles += 1
        if d.reason:
            self.zero_cycles += 1
            self.get_logger().warn(f"zero command: {d.reason}", throttle_duration_sec=2.0)
        return True

    def stop_commanding(self) -> None:
        """On the way out (Ctrl-C, SIGTERM): in timer mode one last zero command, so that a
        machine holding its last command (sample-and-hold) stops now rather than at its command
        timeout. Not in lockstep mode, where every command steps the simulator."""
        if self.trigger == "timer" and self.context.ok():
            self.pub_cmd.publish(Float64MultiArray(data=list(ZERO_COMMAND)))
            # a reliable writer destroyed right after a write may drop it: wait for the acks
            acked = self.pub_cmd.wait_for_all_acked(Duration(seconds=0.5))
            self.get_logger().info("stopping: sent a zero command" + ("" if acked else " (not acknowledged in 0.5 s)"))

    # ------------------------------------------------------------------ diagnostics
    def stats(self) -> dict:
        lat = np.array(self.latencies_ms) if self.latencies_ms else np.array([math.nan])
        per = np.array(self.periods_ms) if self.periods_ms else np.array([math.nan])
        jit = np.abs(per - 1000.0 / self.rate_hz)
        return {"cycles": self.cycles, "zero_cycles": self.zero_cycles,
                "latency_p50_ms": float(np.percentile(lat, 50)), "latency_p99_ms": float(np.percentile(lat, 99)),
                "jitter_p99_ms": float(np.percentile(jit, 99))}

    def _diagnostics(self) -> None:
        st = DiagnosticStatus()
        st.name = "lhd_policy"
        st.hardware_id = self.policy_path
        s = self.stats()
        ok = self.core.actor is not None
        st.level = DiagnosticStatus.OK if ok else DiagnosticStatus.ERROR
        st.message = "ok" if ok else "no actor loaded"
        st.values = [KeyValue(key=k, value=f"{v:.4g}" if isinstance(v, float) else str(v)) for k, v in s.items()]
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status = [st]
        self.pub_diag.publish(arr)


def main(args=None) -> int:
    return run_node(PolicyNode, "lhd_policy", args, before_destroy=lambda n: n.stop_commanding())


if __name__ == "__main__":
    raise SystemExit(main())
