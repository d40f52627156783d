"""`ros2 run lhd_loading_ros cmd_mux_node`: the only writer of <prefix>/cmd, which the bridge
obeys; it picks one of several command sources (twist_mux style; rules in policy/cmd_mux.py and
docs/teleop.md).

In:  the sources of `sources_file` (config/cmd_mux.yaml: teleop <prefix>/cmd/teleop priority 100,
     not gated; auto <prefix>/cmd/auto priority 10, gated), std_msgs/Float64MultiArray
     [u_wheels, u_boom, u_bucket] rad/s; <prefix>/episode (diagnostic_msgs/DiagnosticStatus, key
     `state`: gated sources pass only while it is `running`, and a running status older than
     `status_timeout` ends the attempt); <prefix>/estop (std_msgs/Bool, the lock: true blocks every
     source).
Out: <prefix>/cmd                 every accepted message of the selected source at once (3 finite
                                  values, clamped to the task's actuator ranges; others rejected
                                  and counted); a zero at once when the selected source goes away
                                  (timeout, attempt end, e-stop); zeros at idle_rate_hz while no
                                  source is selected;
     <prefix>/cmd_mux/active      std_msgs/String, latched: the selected source, `none` or `estop`;
     /diagnostics                 selection (with the reason) and sources (ages, counters).
"""
from __future__ import annotations

import time
from functools import partial

from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.duration import Duration
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Bool, Float64MultiArray, String

from lhd_loading_ros.policy.actuator_limits import ZERO, ActuatorLimits
from lhd_loading_ros.policy.cmd_mux import ESTOP, CommandMux, MuxConfigError, load_sources
from lhd_loading_ros.policy.shipped import shipped_config
from lhd_loading_ros.ros.diagnostics import ERROR, OK, WARN, Diagnostics
from lhd_loading_ros.ros.params import Param, Params, steady_timer, topic_prefix
from lhd_loading_ros.ros.qos import COMMAND_QOS, LATCHED_QOS, STATUS_QOS
from lhd_loading_ros.ros.run import run_node
from lhd_loading_ros.task.attempt import STATUS_TIMEOUT_S
from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.task.params import TaskParams

# QoS: command sources in and <prefix>/cmd out COMMAND_QOS (reliable, keep-last 1: only the newest
# command counts, and every timeout is judged on arrival). <prefix>/episode in STATUS_QOS (reliable +
# transient local) so that a mux started late knows whether an attempt is running. The e-stop in:
# LATCHED_QOS for the latched publishers of the contract (teleop node, `lhd estop`), plus reliable
# volatile, which also matches a plain `ros2 topic pub` (a volatile publisher cannot match the
# latched subscription; that mismatch is expected and not reported). cmd_mux/active out
# LATCHED_QOS: `lhd estop` and a late tool read the current selection.
ESTOP_ANY_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                           durability=DurabilityPolicy.VOLATILE)
TICK_S = 0.01           # source timeouts are noticed within this; idle zeros are paced by idle_rate_hz
RECENT_S = 5.0          # diagnostics: rejections this recent make the report WARN


class CmdMuxNode(Node):
    def __init__(self, **node_kwargs):
        super().__init__("lhd_cmd_mux", **node_kwargs)
        self.params = Params(self, [
            Param("config", "", "lhd_params.yaml to use (actuator ranges); empty: found automatically"),
            Param("sources_file", "", "the sources (name, topic, priority, timeout, gated) as YAML; empty: the "
                  "shipped config/cmd_mux.yaml"),
            Param("idle_rate_hz", 10.0, "zero commands per second while no source is selected (the bridge holds "
                  "the machine stopped)", lo=1.0, hi=100.0, on_change=self._set_idle_rate),
            Param("status_timeout", STATUS_TIMEOUT_S, "s: a running attempt whose <prefix>/episode status is older than this "
                  "has ended (the supervisor crashed or hung; it publishes at least every 0.2 s): the gated sources "
                  "stop, a zero at once; 0: never (a status publisher that sends only on change). Fixed at start: "
                  "it guards against a stalled supervisor (set to 0 at run time on every node, it let the machine "
                  "drive on through one)", lo=0.0, hi=60.0),
            Param("namespace_prefix", "/lhd", "topic prefix in the root namespace (under a namespace, the "
                  "namespace is the prefix)"),
        ])
        gp = self.params.__getitem__
        limits = ActuatorLimits.from_params(TaskParams.from_config(load_config(gp("config") or None)))
        try:
            path = gp("sources_file") or str(shipped_config("cmd_mux.yaml"))
            sources = load_sources(path)
        except (MuxConfigError, FileNotFoundError) as exc:
            raise ValueError(f"parameter 'sources_file': {exc}") from None
        self.sources_file = path
        self.mux = CommandMux(sources, limits, 1.0 / gp("idle_rate_hz"), status_timeout=gp("status_timeout"))
        ns = topic_prefix(self, gp("namespace_prefix"))
        self.topics = {s.name: (s.topic if s.topic.startswith("/") else f"{ns}/{s.topic.strip('/')}") for s in sources}
        self.pub_cmd = self.create_publisher(Float64MultiArray, f"{ns}/cmd", COMMAND_QOS)
        self.pub_active = self.create_publisher(String, f"{ns}/cmd_mux/active", LATCHED_QOS)
        for s in sources:
            self.create_subscription(Float64MultiArray, self.topics[s.name], partial(self._on_command, s.name),
                                     COMMAND_QOS)
        self.create_subscription(DiagnosticStatus, f"{ns}/episode", self._on_episode, STATUS_QOS)
        quiet = SubscriptionEventCallbacks(incompatible_qos=lambda _: None)
        self.create_subscription(Bool, f"{ns}/estop", self._on_estop, LATCHED_QOS, event_callbacks=quiet)
        self.create_subscription(Bool, f"{ns}/estop", self._on_estop, ESTOP_ANY_QOS)
        self.published = 0
        self._lost_back_warned = False
        self.forwarded_at: dict[str, float] = {}
        self._active = None
        self._rejected_at = -1e9
        self._publish_active()
        steady_timer(self, TICK_S, self._on_tick)
        self.diagnostics = Diagnostics(self, {"selection": self._diag_selection, "sources": self._diag_sources},
                                       hardware_id=f"{ns}/cmd")
        self.get_logger().info("sources: " + "; ".join(
            f"{s.name} {self.topics[s.name]} priority {s.priority} timeout {s.timeout:g} s"
            f"{' gated (running only)' if s.gated else ''}" for s in sources) + f"; output {ns}/cmd")

    def _set_idle_rate(self, hz: float) -> None:
        self.mux.idle_period = 1.0 / hz

    # ------------------------------------------------------------------ events
    def _emit(self, commands: list) -> None:
        for cmd in commands:
            self.pub_cmd.publish(Float64MultiArray(data=list(cmd)))
            self.published += 1
        self._publish_active()

    def _publish_active(self) -> None:
        active = self.mux.active
        if active != self._active:
            if self._active is not None:
                self.get_logger().info(f"active: {self._active} -> {active} ({self.mux.explain(time.monotonic())})")
            self._active = active
            self.pub_active.publish(String(data=active))

    def _on_command(self, name: str, msg: Float64MultiArray) -> None:
        st = self.mux.states[name]
        rejected = st.rejected
        self._emit(self.mux.on_command(name, msg.data, time.monotonic()))
        if st.rejected > rejected:
            self._rejected_at = time.monotonic()
            self.get_logger().warn(f"rejected a command from {name} ({self.topics[name]}): {st.last_rejection}",
                                   throttle_duration_sec=1.0)

    def _on_episode(self, msg: DiagnosticStatus) -> None:
        kv = {k.key: k.value for k in msg.values}
        state, was = kv.get("state", msg.message), self.mux.episode_state
        self._emit(self.mux.on_episode(state, time.monotonic(), kv.get("episode")))
        if self.mux.episode_state != state:     # a lost attempt's `running` again: it stays ended
            if not self._lost_back_warned:
                self._lost_back_warned = True
                self.get_logger().warn(f"attempt {kv.get('episode')}'s status came back after it had stopped "
                                       "arriving: not resumed, zero commands until the next attempt")
        elif state != was:
            self._lost_back_warned = False
            self.get_logger().info(f"attempt state: {was or 'unknown'} -> {state}")

    def _on_estop(self, msg: Bool) -> None:
        engaged = bool(msg.data)
        if engaged != self.mux.estop:
            if engaged:
                self.get_logger().error("E-STOP engaged: every source blocked, zero commands")
            else:
                self.get_logger().warn("e-stop released: sources resume once they have been silent for their timeout")
        self._emit(self.mux.on_estop(engaged, time.monotonic()))

    def _on_tick(self) -> None:
        was = self.mux.episode_state
        self._emit(self.mux.tick(time.monotonic()))
        if self.mux.episode_state != was:
            self.get_logger().error(f"attempt state: {was} -> {self.mux.episode_state}: no <prefix>/episode status for "
                                    f"{self.mux.status_lost_after:.1f} s (status_timeout {self.mux.status_timeout:g} s); "
                                    "the supervisor stopped or hung, zero commands until the next attempt")

    def stop_commanding(self) -> None:
        """On the way out: one last zero, so the bridge stops now rather than at its timeout."""
        if self.context.ok():
            self.pub_cmd.publish(Float64MultiArray(data=list(ZERO)))
            self.pub_cmd.wait_for_all_acked(Duration(seconds=0.5))

    # ------------------------------------------------------------------ diagnostics
    def _diag_selection(self):
        now = time.monotonic()
        m = self.mux
        values = {"active": m.active, "attempt_state": m.episode_state or "unknown", "estop": m.estop,
                  "published": self.published, "zeros_at_once": m.zeros_at_once}
        if m.active == ESTOP:
            return ERROR, m.explain(now), values
        if now - self._rejected_at < RECENT_S:
            bad = [f"{n}: {st.last_rejection}" for n, st in m.states.items() if st.last_rejection]
            return WARN, f"{m.explain(now)}; rejected commands: {'; '.join(bad)}", values
        return OK, m.explain(now), values

    def _diag_sources(self):
        now = time.monotonic()
        values = {}
        for s in self.mux.sources:
            st = self.mux.states[s.name]
            age = "never" if st.last_arrival is None else f"{now - st.last_arrival:.2f} s"
            values[s.name] = (f"{self.topics[s.name]} priority {s.priority} timeout {s.timeout:g} s gated {s.gated}: "
                              f"{self.mux.why_not(s, now)}; last {age}; received {st.received} forwarded {st.forwarded} "
                              f"rejected {st.rejected} clamped {st.clamped} cut {st.dropped_cut} gated {st.dropped_gated}")
            values[f"{s.name}_rejected"] = st.rejected
            values[f"{s.name}_clamped"] = st.clamped
        return OK, f"{len(self.mux.sources)} sources from {self.sources_file}", values


def main(args=None) -> int:
    return run_node(CmdMuxNode, "lhd_cmd_mux", args, before_destroy=lambda n: n.stop_commanding())


if __name__ == "__main__":
    raise SystemExit(main())
