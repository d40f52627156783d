"""`ros2 run lhd_loading_ros teleop_node`: a gamepad drives the LHD (the paper's Teleop
baseline), through the command mux.

In:  sensor_msgs/Joy on `joy_topic` (/joy, absolute: where the joy driver publishes), and
     <prefix>/estop (std_msgs/Bool: the e-stop as the CLI or another operator set it).
Out: <prefix>/cmd/teleop  std_msgs/Float64MultiArray [u_wheels, u_boom, u_bucket] rad/s, only
                          while the deadman is held, one per Joy message (the joy driver's
                          autorepeat sets the rate); on release one zero, then silence;
     <prefix>/estop       std_msgs/Bool, latched: true at once when the e-stop button is pressed,
                          false only after the release combination; the node also mirrors what it
                          hears there, so its latched value is the current one for a late joiner;
     /diagnostics         joystick (messages, rate, bad input) and teleop (state).
Mapping: `mapping` names a shipped file (config/teleop/<name>.yaml: xbox, ps4, f710,
game_controller) or is a path; the rules are in policy/joy_mapping.py and docs/teleop.md.
Safety: Joy messages stopping for `joy_timeout` while commanding -> one zero, then silence; a
malformed Joy (too few axes / buttons for the mapping, NaN, out of [-1, 1]) is ignored with a
throttled warning and counted, and stops the machine if it was commanding; every stop other than
a release asks for a fresh deadman press.
"""
from __future__ import annotations

import time
from collections import deque
from pathlib import Path

from rclpy.duration import Duration
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import Joy
from std_msgs.msg import Bool, Float64MultiArray

from lhd_loading_ros.policy.actuator_limits import ZERO, ActuatorLimits
from lhd_loading_ros.policy.joy_mapping import SHIPPED, MappingError, TeleopCore, TeleopOutput, load_mapping
from lhd_loading_ros.policy.shipped import shipped_config
from lhd_loading_ros.ros.diagnostics import ERROR, OK, WARN, Diagnostics
from lhd_loading_ros.ros.params import Param, Params, steady_timer, topic_prefix
from lhd_loading_ros.ros.qos import COMMAND_QOS, LATCHED_QOS
from lhd_loading_ros.ros.run import run_node
from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.task.params import TaskParams

# QoS: Joy in with sensor-data QoS (best effort): matches the joy driver (reliable, depth 10) and
# any best-effort relay, and an old joystick sample is worth nothing. Commands out COMMAND_QOS
# (reliable, keep-last 1: only the newest counts; the mux times out on arrival). E-stop out
# LATCHED_QOS: a mux or supervisor that starts later still learns that the e-stop is engaged.
# E-stop in: LATCHED_QOS for latched publishers (the contract), plus reliable volatile, which also
# matches a `ros2 topic pub` (volatile); a volatile publisher is incompatible with the latched
# subscription by design, so that mismatch is not reported.
ESTOP_ANY_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                           durability=DurabilityPolicy.VOLATILE)
TIMER_S = 0.02          # the Joy-timeout check: the stop leaves at most this long after joy_timeout
RATE_WINDOW_S = 2.0
OWN_ESTOP_KEPT = 32      # our latest e-stop publications, recognised when they come back to us
OVERTAKEN_NS = 1_000_000_000   # a release up to 1 s older than a sample taken before is dropped (the supervisor's
                               # rule for latched inputs; beyond, clocks of two machines may differ); an engage never


def resolve_mapping(value: str) -> Path:
    if value in SHIPPED:
        try:
            return shipped_config(f"teleop/{value}.yaml")
        except FileNotFoundError as exc:
            raise ValueError(f"parameter 'mapping' = {value!r}: {exc}") from None
    p = Path(value)
    if not p.is_file():
        raise ValueError(f"parameter 'mapping' = {value!r} is neither a shipped mapping {SHIPPED} nor a readable file")
    return p


class TeleopNode(Node):
    def __init__(self, **node_kwargs):
        super().__init__("lhd_teleop", **node_kwargs)
        self.params = Params(self, [
            Param("config", "", "lhd_params.yaml to use (actuator ranges); empty: found automatically"),
            Param("mapping", "xbox", f"gamepad mapping: one of {', '.join(SHIPPED)} (config/teleop/<name>.yaml) "
                  "or the path of a mapping YAML"),
            Param("joy_topic", "/joy", "sensor_msgs/Joy input (absolute: the joy driver publishes /joy)"),
            Param("joy_timeout", 0.5, "s without a Joy message while the deadman is held before the machine is "
                  "stopped (a dead controller must not keep it moving)", lo=0.05, hi=5.0,
                  on_change=lambda v: setattr(self.core, "joy_timeout", v)),
            Param("namespace_prefix", "/lhd", "topic prefix in the root namespace (under a namespace, the "
                  "namespace is the prefix)"),
        ])
        gp = self.params.__getitem__
        limits = ActuatorLimits.from_params(TaskParams.from_config(load_config(gp("config") or None)))
        path = resolve_mapping(gp("mapping"))
        try:
            mapping = load_mapping(path)
        except MappingError as exc:
            raise ValueError(f"parameter 'mapping': {exc}") from None
        self.core = TeleopCore(mapping, limits, gp("joy_timeout"))
        self.joy_topic = gp("joy_topic")
        ns = topic_prefix(self, gp("namespace_prefix"))
        self._estop_published: bool | None = None
        self._estop_heard: bool | None = None
        self._estop_own: deque = deque(maxlen=OWN_ESTOP_KEPT)  # (ns before, ns after, value) of our publishes
        self._estop_newest_ns = -1         # source stamp of the newest e-stop sample taken from another node
        self._arrivals: deque = deque()
        self.pub_cmd = self.create_publisher(Float64MultiArray, f"{ns}/cmd/teleop", COMMAND_QOS)
        self.pub_estop = self.create_publisher(Bool, f"{ns}/estop", LATCHED_QOS)
        self.create_subscription(Joy, self.joy_topic, self._on_joy, qos_profile_sensor_data)
        quiet = SubscriptionEventCallbacks(incompatible_qos=lambda _: None)
        self.create_subscription(Bool, f"{ns}/estop", self._on_estop, LATCHED_QOS, event_callbacks=quiet)
        self.create_subscription(Bool, f"{ns}/estop", self._on_estop, ESTOP_ANY_QOS)
        steady_timer(self, TIMER_S, self._on_timer)
        self.diagnostics = Diagnostics(self, {"joystick": self._diag_joystick, "teleop": self._diag_teleop},
                                       hardware_id=mapping.controller or mapping.name)
        m = mapping
        self.get_logger().info(
            f"mapping '{m.name}' from {path} ({m.controller}; {m.driver}): deadman button {m.deadman_button}, e-stop "
            f"button {m.estop_button}, release {'+'.join(map(str, m.estop_release_buttons))} held "
            f"{m.estop_release_hold_s:g} s; Joy on {self.joy_topic}, commands on {ns}/cmd/teleop")

    # ------------------------------------------------------------------ events
    def _apply(self, out: TeleopOutput) -> None:
        if out.estop is not None:            # the e-stop first: it is the urgent one
            self._publish_estop(out.estop)
            if out.estop:
                self.get_logger().error("E-STOP engaged by the gamepad button")
            else:
                self.get_logger().warn("e-stop released with the release combination; press the deadman anew to drive")
        if out.command is not None:
            self.pub_cmd.publish(Float64MultiArray(data=list(out.command)))
        if out.problem:
            self.get_logger().warn(f"Joy ignored: {out.problem}", throttle_duration_sec=2.0)

    def _publish_estop(self, engaged: bool) -> None:
        self._estop_published = engaged
        before = time.time_ns()           # the sample's source stamp lies between the two (system clock)
        self.pub_estop.publish(Bool(data=engaged))
        self._estop_own.append((before, time.time_ns(), engaged))

    def _on_joy(self, msg: Joy) -> None:
        now = time.monotonic()
        self._arrivals.append(now)
        while self._arrivals and now - self._arrivals[0] > RATE_WINDOW_S:
            self._arrivals.popleft()
        out = self.core.on_joy(msg.axes, msg.buttons, now)
        self._apply(out)
        if self.core.state == "wait_release":
            self.get_logger().info("deadman held since before a stop: release it and press it again to drive",
                                   throttle_duration_sec=5.0)

    def _on_timer(self) -> None:
        out = self.core.on_timer(time.monotonic())
        if out.problem:          # not throttled together with the bad-Joy warnings: another cause
            self.get_logger().warn(out.problem, throttle_duration_sec=2.0)
            out.problem = ""
        self._apply(out)

    def _on_estop(self, msg: Bool, info) -> None:
        """An e-stop sample from the latched or the volatile subscription. Taken only if it is
        another node's and not a release older than a sample taken before: our own publications
        come back to us, and after a stall the two subscriptions deliver older samples after newer
        ones. Mirroring
        an older sample, or our own echo of one, made two nodes' latched values chase each other
        (thousands of messages a second, the value left wherever it stopped: a review, 2026-11-28)."""
        engaged = bool(msg.data)
        stamp = int(info["source_timestamp"])
        if any(a <= stamp <= b and v == engaged for a, b, v in self._estop_own):
            return                        # our own publication
        if stamp == self._estop_newest_ns:
            return                        # the same sample by the other subscription
        if not engaged and 0 < self._estop_newest_ns - stamp < OVERTAKEN_NS:
            return                        # a release overtaken by a newer sample
        # an engage is never dropped, however old its stamp: another computer's clock may run behind
        # ours, and a wrongly kept engage only asks for one more release (a review, 2026-11-28)
        self._estop_newest_ns = max(self._estop_newest_ns, stamp)
        self._estop_heard = engaged
        out = self.core.on_estop(engaged)
        if out.command is not None:
            self.get_logger().error(f"e-stop engaged on the {self.pub_estop.topic_name} topic: stopped")
        self._apply(out)
        if engaged != self._estop_published:   # keep this node's latched value the current one
            self._publish_estop(engaged)

    def stop_commanding(self) -> None:
        """On the way out: a zero if the operator was driving (the mux would time out anyway)."""
        if self.core.commanding and self.context.ok():
            self.pub_cmd.publish(Float64MultiArray(data=list(ZERO)))
            self.pub_cmd.wait_for_all_acked(Duration(seconds=0.5))
        self.pub_estop.wait_for_all_acked(Duration(seconds=0.5))

    # ------------------------------------------------------------------ diagnostics
    def _diag_joystick(self):
        c = self.core
        now = time.monotonic()
        rate = len(self._arrivals) / RATE_WINDOW_S if self._arrivals and now - self._arrivals[-1] < RATE_WINDOW_S else 0.0
        values = {"mapping": c.mapping.name, "mapping_file": c.mapping.source, "joy_topic": self.joy_topic,
                  "messages": c.joy_messages, "rejected": c.bad_joy, "rate_hz": rate,
                  "needs": f"{c.mapping.needed_axes} axes, {c.mapping.needed_buttons} buttons",
                  "last_problem": c.last_problem or "none"}
        if c.last_joy is None and c.joy_messages == 0:
            return WARN, f"no Joy message on {self.joy_topic} yet: is the joy driver running?", values
        if c.last_was_bad:
            return ERROR, f"Joy messages unusable: {c.last_problem}", values
        age = now - c.last_joy
        values["last_age_s"] = age
        if age > c.joy_timeout:
            return WARN, f"no Joy message for {age:.1f} s (joy driver stopped, controller off or out of range)", values
        if rate and rate < 1.0 / c.joy_timeout:
            return WARN, (f"Joy at {rate:.1f} Hz, slower than 1/joy_timeout: set the joy driver's autorepeat_rate "
                          "to 10 Hz or more"), values
        return OK, f"Joy at {rate:.0f} Hz", values

    def _diag_teleop(self):
        c = self.core
        m = c.mapping
        values = {"state": c.state, "commands": c.commands, "forced_stops": c.forced_stops,
                  "estop_heard": "unknown" if self._estop_heard is None else self._estop_heard,
                  "triggers_seen_at_rest": sorted(c.armed)}
        if c.state == "estop":
            return ERROR, (f"e-stop engaged: release with buttons {'+'.join(map(str, m.estop_release_buttons))} held "
                           f"{m.estop_release_hold_s:g} s (or `lhd estop off`)"), values
        if c.state == "wait_release":
            return WARN, "deadman held since before a stop: release and press it again", values
        if c.state == "commanding":
            return OK, "operator driving (deadman held)", values
        return OK, "idle (deadman released)", values


def main(args=None) -> int:
    return run_node(TeleopNode, "lhd_teleop", args, before_destroy=lambda n: n.stop_commanding())


if __name__ == "__main__":
    raise SystemExit(main())
