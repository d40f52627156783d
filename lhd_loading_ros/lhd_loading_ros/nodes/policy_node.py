"""`ros2 run lhd_loading_ros policy_node`: a loading controller at 10 Hz, the exported actor
(controller:=actor, the default), the Tampier-style heuristic (controller:=tampier) or the
training's demonstration maneuver on the end zone it is given (controller:=teacher; policy/teacher.py).

It moves the machine only while an attempt is running: /lhd/episode (published by the sim node in
simulation, by the episode supervisor on hardware) must say state = running. Before any status has
arrived (no sim node, no supervisor), in any other state (idle, armed, success, failure, timeout,
estop, lost_input, aborted), once the publisher of /lhd/episode is gone, or once a running status
is older than `status_timeout` (1.5 s: the publisher hung or crashed before DDS noticed; that
attempt then never resumes), it publishes nothing,
except ONE zero command on each transition out of running (sent when the status arrives, so the
machine stops within one message, not one control period); /diagnostics `decision` says why
("no attempt running (no /lhd/episode publisher: ...)", "attempt <state>: waiting to be armed").
Each new running attempt (a new `episode` key, or running after another state) resets the
controller (the heuristic's state machine starts again at its approach).

While running, every cycle it rebuilds the task state from the latest topics (forward kinematics
from /lhd/odom and /lhd/joint_states, drift flags, slope, end zone) and decides through one path
(policy.core.DecisionCore): the actor builds the 12-vector with the environment's own code
(lhd_loading_ros.task.observation), runs (numpy, no torch), and its variant's deployment filter
applies; the heuristic steps its state machine (policy/tampier.py, thresholds in
config/tampier.yaml); the teacher runs the demonstrations' maneuver on the tip pose, the drift flags
and the end zone (its setting: the parameter file's training.demo_*). All publish /lhd/cmd in rad/s (the actor also /lhd/observation). The zero
command (wheels stopped, arm held) and a throttled warning, with the reason on /diagnostics, when:
an input is missing or older than its timeout (input_timeout for the 10 Hz inputs; slope_timeout /
end_zone_timeout for the slow ones, none by default: a latched constant never goes stale), a value
is NaN, no actor is loaded, or the slope is outside the range the actor was trained on (the policy
card's trained_ranges; the heuristic has no trained range).

The slope of an attempt (slope_source = attempt, the default): while an attempt runs and its
/lhd/episode status carries the slope it was armed with (the supervisor's slope_deg, the sim
node's slope_rad), that slope is the observation's alpha for the whole attempt; /pile/slope
updates are taken again when the attempt ends. The paper's alpha is the pile's slope, measured
before loading; a LiDAR fit made while the bucket cuts the face and the machine stands in the
scan is not it (in the digital twin it drifted from 29.8 to 31.8 deg on a 30 deg pile during
attempts, past the trained range, and the actor was refused: docs/twin.md). slope_source = live
takes every /pile/slope update, as before; a status without a slope (a test's, a third-party
supervisor's) leaves the live slope in use. The end zone likewise: the supervisor's status carries
the zones it froze at arming (`end_zone`), and while the attempt runs x_max is that one, not the
end-zone node's live estimate (in the twin it jumped from 0.885 to 1.090 m in the middle of a
30 deg attempt, truth 0.910 m, as the bucket hid the face: docs/twin.md "Runs 43-46").

trigger = timer     10 Hz on the steady clock (the real machine; sim node in realtime mode),
                    with use_sim_time too: the loop must not stall on a /clock that holds still
trigger = lockstep  one decision per state of the sim node in lockstep mode: when
                    /lhd/joint_states, /lhd/odom and /lhd/episode carry the same stamp
trigger = odom      a decision as each fresh /lhd/odom arrives (on hardware the ArUco node's, one
                    per camera frame), at most rate_hz a second: an odometry message sooner than
                    1/rate_hz - odom_margin after the last decision is taken as input but decides
                    nothing. The paper's 10 Hz loop, aligned to the camera: the command leaves
                    as soon as the image it depends on is measured, instead of waiting up to a
                    whole period for the next timer tick (docs/twin_latency.md). A steady timer
                    stays as the fallback (checked at 4 x rate_hz): when no decision came for
                    1.5 periods after an odometry-triggered one (odometry late or stopped), or
                    for one period after a fallback one, it decides from the latest inputs, so
                    commands keep coming at rate_hz and turn into the zero command once the
                    odometry is older than input_timeout; a late odometry message never has
                    its decision taken by a timer tick that happened to come first.

Each decision while running is also published on <prefix>/policy/decision (DiagnosticStatus,
after the command): message = what triggered it (timer | odom | fallback | lockstep), keys
odom_stamp_ns (header stamp of the odometry it used: on hardware the camera frame's capture
time), mono_ns (CLOCK_MONOTONIC when the command was published), decided_mono_ns (trigger odom:
when the decision was taken, the clock of its rate limit; otherwise mono_ns), command ("u_w,u_boom,u_bucket"),
reason (empty, or why the command is the zero one), observation (the 12 normalised values the actor saw,
OBS_NAMES order; empty when none was built). `lhd bench twin` matches these with the
command frames on the serial line.
"""
from __future__ import annotations

import math
import time
from collections import deque

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from nav_msgs.msg import Odometry
from rclpy.duration import Duration
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float32MultiArray, Float64, Float64MultiArray

from lhd_loading_ros.task.attempt import STATUS_TIMEOUT_S
from lhd_loading_ros.task.config import config_name, load_config
from lhd_loading_ros.task.kinematics import ArmKinematics
from lhd_loading_ros.task.params import TaskParams
from lhd_loading_ros.policy.status_watch import LostAttempts, StatusWatch
from lhd_loading_ros.policy.core import INPUTS, SLOW_INPUTS, Inputs, PolicyCore, ZERO_COMMAND
from lhd_loading_ros.policy.actor_file import PolicyFileError, default_policy_dir, load_policy  # noqa: F401 (re-exported)
from lhd_loading_ros.policy.tampier import TampierCore, default_tampier_path, load_tampier_config
from lhd_loading_ros.policy.teacher import TeacherCore, TeacherSetting
from lhd_loading_ros.ros.diagnostics import ERROR, OK, WARN, Diagnostics
from lhd_loading_ros.ros.params import Param, Params, steady_timer, topic_prefix
from lhd_loading_ros.ros.qos import COMMAND_QOS, MEASUREMENT_QOS, STATUS_QOS
from lhd_loading_ros.ros.run import run_node

# QoS (lhd_loading_ros.ros.qos). Inputs: `input_qos` = sensor_data (best effort) matches every
# publisher, reliable or not (the ArUco node publishes odometry best effort); `reliable`
# (MEASUREMENT_QOS) is for lockstep runs, where a lost state would stall the loop. The slow
# inputs (slope, end zone) have a second subscription, reliable + transient local (STATUS_QOS),
# which alone receives what a latched publisher sent before this node started; it does not
# match a volatile publisher (DDS), which the first one does. Commands out: COMMAND_QOS.
# Observation and decision trace out: MEASUREMENT_QOS. Episode status in: STATUS_QOS (transient local: a node started
# during an attempt learns at once whether it may command).
TRIGGERS = ("timer", "lockstep", "odom")


CMD_TOPICS = ("cmd", "cmd/auto")


def _cmd_topic_problem(value: str) -> str | None:
    # only these two: any other relative name could be the mux's ungated, highest-priority gamepad source
    # (cmd/teleop), which would put a controller above the operator (a review)
    if value not in CMD_TOPICS:
        return ("expected cmd (straight to the sim node or a bridge without a mux) or cmd/auto (through the command "
                "mux), relative to the prefix")
    return None

CONTROLLERS = ("actor", "tampier", "teacher")
SLOPE_SOURCES = ("attempt", "live")
RUNNING = "running"              # the only /lhd/episode state in which a controller may move the machine
NO_PUBLISHER = "no attempt running (no /lhd/episode publisher: start the sim node or the supervisor)"
FALLBACK_CHECKS = 4             # trigger odom: fallback checks per control period
FALLBACK_AFTER_ODOM = 1.5       # periods without a decision after an odometry-triggered one
OVERTAKEN_NS = 1_000_000_000    # a slow-input sample this much older than the one in use came late
# |norm - 1| of an odometry quaternion beyond this is refused: a unit one (float32 publishers: about 1e-7)
QUAT_NORM_TOL = 1e-3
# zero-command reasons on /diagnostics: these need a person (wrong pile, wrong actor), the rest
# (inputs not there yet or stale, a NaN) may clear by themselves
ERROR_KINDS = ("no_actor", "out_of_range", "actor_output")


def stamp_ns(stamp) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


class PolicyNode(Node):
    def __init__(self, **node_kwargs):
        super().__init__("lhd_policy", **node_kwargs)
        # the parameter file first: it gives the defaults and ranges of the others
        cfg_path = Params(self, [Param("config", "", "lhd_params.yaml to use; empty: found automatically "
                                       "(LHD_CONFIG, then the package's)")])["config"] or None
        cfg = load_config(cfg_path)
        p = TaskParams.from_config(cfg)
        self.params = Params(self, [
            Param("controller", "actor", "actor: the exported actor (policy_dir); tampier: the Tampier-style "
                  "heuristic (tampier_config); teacher: the training's demonstration maneuver on the end zone "
                  "(the parameter file's training.demo_*)", choices=CONTROLLERS),
            Param("policy_dir", "", "exported actor (actor.npz + policy.json); empty: the shipped policies/rld"),
            Param("tampier_config", "", "controller tampier: its thresholds (tampier.yaml); empty: found "
                  "automatically (LHD_TAMPIER_CONFIG, then the package's config/tampier.yaml)"),
            Param("teacher_drift_confirm", 1, "controller teacher: consecutive decisions a drift flag must be up "
                  "before it starts the lift; 1: the training's teacher (the simulator's flags are true slip); "
                  "only fresh drift samples count, a zero command restarts the count; on the machine the wheels read "
                  "as slipping while they spin up from rest (config/real_machine.yaml: 6)",
                  lo=1, hi=50),
            Param("rate_hz", float(cfg["paper"]["control"]["frequency_hz"]), "decisions per second (trigger timer)",
                  lo=0.1, hi=1000.0),
            Param("input_timeout", 0.5, "s: a 10 Hz input (joints, odometry, drift) older than this gives the "
                  "zero command", lo=0.01, hi=60.0, on_change=lambda v: setattr(self, "input_timeout", v),
                  warn_change="a longer input timeout keeps commanding on stale joints, odometry or drift flags"),
            Param("slope_timeout", 0.0, "s: a slope older than this gives the zero command; 0: no timeout (a "
                  "latched constant, e.g. a surveyed pile)", lo=0.0, hi=3600.0,
                  on_change=lambda v: self._set_slow_timeout("slope", v)),
            Param("slope_source", "attempt", "attempt: while an attempt runs, the slope and the end zone it was "
                  "armed with (the /lhd/episode status' slope_rad or slope_deg and end_zone, when it carries them); "
                  "live: every /pile/slope and /pile/end_zone update", choices=SLOPE_SOURCES, on_change=lambda v: setattr(self, "slope_source", v)),
            Param("end_zone_timeout", 0.0, "s: an end zone older than this gives the zero command; 0: no timeout",
                  lo=0.0, hi=3600.0, on_change=lambda v: self._set_slow_timeout("end_zone", v)),
            Param("trigger", "timer", "timer: rate_hz on the steady clock; lockstep: one decision per sim-node "
                  "state; odom: one per fresh /lhd/odom, at most rate_hz, the rate_hz timer as fallback",
                  choices=TRIGGERS),
            Param("odom_margin", 0.01, "s, trigger odom: odometry sooner than 1/rate_hz minus this after the last "
                  "decision decides nothing (absorbs the camera's jitter)", lo=0.0, hi=1.0,
                  on_change=lambda v: setattr(self, "odom_margin", v)),
            Param("input_qos", "sensor_data", "sensor_data: best effort, matches any publisher; reliable: for "
                  "lockstep", choices=("sensor_data", "reliable")),
            Param("status_timeout", STATUS_TIMEOUT_S, "s: a running attempt whose /lhd/episode status is older than this has "
                  "ended (the supervisor or sim node crashed or hung; they publish at least every 0.2 s): one zero "
                  "command, and that attempt does not resume; 0: never (a status publisher that sends only on "
                  "change). Not in trigger lockstep, where the sim node waits for this node. Fixed at start: it "
                  "guards against a stalled supervisor (set to 0 at run time on every node, it let the machine drive "
                  "on through one)", lo=0.0, hi=60.0),
            Param("namespace_prefix", "/lhd", "topic prefix in the root namespace (under a namespace, the "
                  "namespace is the prefix)"),
            Param("cmd_topic", "cmd", "where the commands go, relative to the prefix: cmd (straight to the sim node "
                  "or the bridge) or cmd/auto (through the command mux: the real machine). A parameter, not a remap: "
                  "a remap of the absolute /lhd/cmd did not match under a namespace, and the controller wrote "
                  "straight to the bridge past the mux (a review, 2026-11-29)", check=_cmd_topic_problem),
        ])
        gp = self.params.__getitem__
        self.rate_hz = gp("rate_hz")
        self.status_timeout = gp("status_timeout")
        self.input_timeout = gp("input_timeout")
        self.slow_timeouts: dict[str, float] = {}
        for name in SLOW_INPUTS:
            self._set_slow_timeout(name, gp(f"{name}_timeout"))
        self.trigger = gp("trigger")
        self.odom_margin = gp("odom_margin")
        self.slope_source = gp("slope_source")
        self.attempt_held = {}           # slope / end_zone -> the running attempt's armed value in use, or None
        self._live_held = {}             # slope / end_zone -> (value, info, arrival) of a live sample held back
        qin = qos_profile_sensor_data if gp("input_qos") == "sensor_data" else MEASUREMENT_QOS
        ns = topic_prefix(self, gp("namespace_prefix"))

        self.controller = gp("controller")
        if self.controller == "tampier":
            # a bad or missing tampier.yaml is a ConfigError (a ValueError): one line, exit status 2
            path = gp("tampier_config") or str(default_tampier_path())
            tp = load_tampier_config(path)
            dt = p.control_dt if self.trigger == "lockstep" else 1.0 / self.rate_hz
            self.core = TampierCore(tp, p, ArmKinematics.from_config(cfg), dt)
            self.get_logger().info(f"Tampier-style heuristic from {path} (control period {dt:g} s)")
        elif self.controller == "teacher":
            # a bad training.demo_* value is a ValueError: one line, exit status 2
            setting = TeacherSetting.from_config(cfg)
            path = f"{config_name(cfg_path)} training.demo_*"
            confirm = gp("teacher_drift_confirm")
            self.core = TeacherCore(setting, p, ArmKinematics.from_config(cfg), confirm)
            self.get_logger().info(f"teacher (the demonstrations' maneuver) from {path}: crowd {setting.crowd:g}, "
                                   f"pre-curl {setting.pre_curl:g} rad, end-zone stop {setting.end_zone_stop:g} m, "
                                   f"drift confirmed after {confirm} decision(s)")
        else:
            path = gp("policy_dir") or str(default_policy_dir("rld"))
            actor, variant, slope_range = None, "rld", None
            try:
                # an actor trained with another observation scaling (e.g. 10-35 deg piles) is refused:
                # it would read this config's inputs as others
                pol = load_policy(path).check_config(cfg)
                lo, hi, source = pol.trained_slope_range_deg(cfg)
                actor, variant, slope_range = pol.actor, pol.variant, (lo, hi)
                if pol.meta.get("config_hash") not in (None, "") and not pol.config_matches(cfg):
                    self.get_logger().warn(f"policy {path} was trained with another parameter file "
                                           f"(config hash {pol.meta['config_hash']}); check the filters and ranges")
                elif (note := pol.sim_change_note(cfg)) is not None:
                    self.get_logger().info(f"policy {path}: {note}")
                self.get_logger().info(f"loaded {variant.upper()} actor from {path} (sizes {pol.actor.sizes}); "
                                       f"trained on slopes {lo:g}-{hi:g} deg ({source})")
            except PolicyFileError as exc:
                self.get_logger().error(f"no actor: {exc}. Publishing zero commands.")
            self.core = PolicyCore(actor, variant, p, ArmKinematics.from_config(cfg), slope_range)
        self.policy_path = path
        self.inputs = Inputs()
        self._slow_source_ns = {}        # source timestamp of the slow-input sample in use
        self.episode_state = None        # None: no /lhd/episode status (or its publisher is gone): no motion
        self.episode_key = None
        self._status_publisher_seen = False
        self.status_watch = StatusWatch()   # the /lhd/episode status' age in this node's running time
        self._lost = LostAttempts()      # the attempts whose status stopped arriving: none resumes (status_watch.py)
        self._lost_keys_heard: set = set()   # those whose running status came back (warned once each)
        self.attempts = 0                # running attempts begun (controller resets)
        self._status_stamp = None
        self._stamps = {"joints": None, "odom": None}
        self._decided_stamp = None
        self.cycles = 0
        self.zero_cycles = 0
        self.last_decision = None        # the latest Decision, for /diagnostics
        self.latencies_ms: deque = deque(maxlen=100_000)
        self.periods_ms: deque = deque(maxlen=100_000)
        self._last_tick = None
        self._last_decision_t = None     # monotonic time of the latest decision (trigger odom)
        self._last_why = None            # what triggered it
        self._decided_mono_ns = None     # its monotonic time in ns, for the decision trace
        self.odom_decisions = self.fallback_decisions = self.odom_skipped = 0

        self.pub_cmd = self.create_publisher(Float64MultiArray, f"{ns}/{gp('cmd_topic')}", COMMAND_QOS)
        self.pub_obs = self.create_publisher(Float32MultiArray, f"{ns}/observation", MEASUREMENT_QOS)
        self.pub_decision = self.create_publisher(DiagnosticStatus, f"{ns}/policy/decision", MEASUREMENT_QOS)
        self.create_subscription(JointState, f"{ns}/joint_states", self._on_js, qin)
        self.create_subscription(Odometry, f"{ns}/odom", self._on_odom, qin)
        self.create_subscription(Bool, f"{ns}/wheel_drift/front", lambda m: self._put("drift_front", bool(m.data)), qin)
        self.create_subscription(Bool, f"{ns}/wheel_drift/rear", lambda m: self._put("drift_rear", bool(m.data)), qin)
        # volatile / best-effort publishers, and latched ones; a volatile publisher is incompatible
        # with the latched subscription by design (the other one takes it): no warning for that
        quiet = SubscriptionEventCallbacks(incompatible_qos=lambda _: None)
        for qos, events in ((qin, None), (STATUS_QOS, quiet)):
            self.create_subscription(Float64, f"{ns}/pile/slope", self._on_slope, qos, event_callbacks=events)
            self.create_subscription(Float64MultiArray, f"{ns}/pile/end_zone", self._on_zone, qos,
                                     event_callbacks=events)
        self.episode_topic = f"{ns}/episode"
        self.create_subscription(DiagnosticStatus, self.episode_topic, self._on_status, STATUS_QOS)
        if self.trigger == "timer":
            steady_timer(self, 1.0 / self.rate_hz, self._on_timer)
        elif self.trigger == "odom":
            steady_timer(self, 1.0 / (FALLBACK_CHECKS * self.rate_hz), self._on_fallback_check)
        what = {"actor": "actor", "tampier": "heuristic", "teacher": "teacher"}[self.controller]
        self.diagnostics = Diagnostics(self, {what: self._diag_controller, "inputs": self._diag_inputs,
                                              "decision": self._diag_decision}, hardware_id=path)

    def _set_slow_timeout(self, name: str, value: float) -> None:
        self.slow_timeouts[name] = value if value > 0 else math.inf

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
            why = f"joint_states without boom/bucket (names {list(msg.name)}); expected joints named boom and bucket"
            self.inputs.reject("joints", why, time.monotonic())
            self.get_logger().warn(why, throttle_duration_sec=2.0)
            return
        self._put("joints", joints)
        self._stamps["joints"] = stamp_ns(msg.header.stamp)
        self._maybe_lockstep()

    def _on_odom(self, msg: Odometry) -> None:
        pp, q = msg.pose.pose.position, msg.pose.pose.orientation
        n = math.sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z)
        if math.isfinite(n) and n > 0.0 and abs(n - 1.0) > QUAT_NORM_TOL:
            # a broken publisher: normalised in silence it was taken as a pose (a review, 2026-11-30); a zero or
            # non-finite one goes on to the refusal with its own reason (task.kinematics.quat_to_mat)
            why = (f"odometry orientation ({q.w:g}, {q.x:g}, {q.y:g}, {q.z:g}) has norm {n:.4g}; expected a unit "
                   f"quaternion (within {QUAT_NORM_TOL:g})")
            self.inputs.reject("odom", why, time.monotonic())
            self.get_logger().warn(why, throttle_duration_sec=2.0)
            return
        self._put("odom", ((pp.x, pp.y, pp.z), (q.w, q.x, q.y, q.z), msg.twist.twist.linear.x))
        self._stamps["odom"] = stamp_ns(msg.header.stamp)
        self._maybe_lockstep()
        if self.trigger == "odom":
            self._on_fresh_odom()

    def _put_slow(self, name: str, value, info) -> None:
        """A slow input arrives through both of its subscriptions when its publisher is reliable:
        the second copy (same source time) and a sample overtaken by a newer one through the other
        subscription are dropped; a much older source time is another publisher, taken."""
        src = info["source_timestamp"]
        held = self._slow_source_ns.get(name)
        if held is not None and 0 <= held - src < OVERTAKEN_NS:
            return
        self._slow_source_ns[name] = src
        self._put(name, value)

    def _on_slope(self, msg: Float64, info) -> None:
        self._on_slow_live("slope", float(msg.data), info)

    def _on_slow_live(self, name: str, value, info) -> None:
        """A live /pile/slope or /pile/end_zone sample: in use, unless the running attempt holds
        the value it was armed with (slope_source attempt); then kept for after the attempt."""
        if self.attempt_held.get(name) is not None:
            kept = self._live_held.get(name)     # the newest by source time (both subscriptions deliver)
            if kept is None or info["source_timestamp"] >= kept[1]["source_timestamp"]:
                self._live_held[name] = (value, info, time.monotonic())
            return
        self._live_held.pop(name, None)
        self._put_slow(name, value, info)

    @staticmethod
    def _armed_values(kv: dict) -> dict:
        """The slope (rad; slope_rad exact, else slope_deg) and end zone ([x_min, x_max, z_min]) an
        attempt's status says it was armed with; a missing or non-finite one is left out."""
        out = {}
        try:
            slope = float(kv["slope_rad"]) if "slope_rad" in kv else math.radians(float(kv["slope_deg"]))
            if math.isfinite(slope):
                out["slope"] = slope
        except (KeyError, ValueError):
            pass
        try:
            zone = tuple(float(v) for v in kv["end_zone"].split(","))
            if len(zone) == 3 and all(math.isfinite(v) for v in zone):
                out["end_zone"] = zone
        except (KeyError, ValueError):
            pass
        return out

    def _hold_attempt_slope(self, kv: dict) -> None:
        """slope_source attempt: while running, the slope and the end zone in the status (the
        supervisor's, frozen at arming; the sim node's exact ones) are the attempt's; out of running
        (or without them in the status) the live ones."""
        armed = self._armed_values(kv) if self.slope_source == "attempt" and self.running() else {}
        for name in ("slope", "end_zone"):
            held, now = self.attempt_held.get(name), armed.get(name)
            self.attempt_held[name] = now
            if now is not None:
                self._slow_source_ns.pop(name, None)    # the next live sample after the attempt is taken
                self._put(name, now)
            elif held is not None:                      # the attempt ended: back to the live value
                self._slow_source_ns.pop(name, None)
                live = self._live_held.pop(name, None)
                if live is not None:                    # one came during the attempt: it is the latest,
                    value, info, t = live               # with its own arrival time (slope/end_zone_timeout)
                    self._slow_source_ns[name] = info["source_timestamp"]
                    self.inputs.put(name, value, t)

    def _on_zone(self, msg: Float64MultiArray, info) -> None:
        if len(msg.data) != 3:
            self.get_logger().warn(f"end_zone must be [x_min, x_max, z_min], got {list(msg.data)}",
                                   throttle_duration_sec=2.0)
            return
        self._on_slow_live("end_zone", tuple(float(v) for v in msg.data), info)

    def running(self) -> bool:
        return self.episode_state == RUNNING

    def _set_episode(self, state, key) -> None:
        """The attempt's state changes: a new running attempt resets the controller; leaving
        running sends the one zero command (now, not at the next control period)."""
        if self._lost.resumes(state, key):
            if key not in self._lost_keys_heard:
                self._lost_keys_heard.add(key)
                self.get_logger().warn(f"attempt {key if key is not None else '(without an episode key)'}'s status "
                                       "came back after it had stopped arriving: the attempt is not resumed (arm a "
                                       "new one)")
            state = "lost"                   # that attempt's running status no longer counts
        was = self.running()
        new_attempt = state == RUNNING and (not was or key != self.episode_key)
        armed_now = state == "armed" and (self.episode_state != "armed" or key != self.episode_key)
        self.episode_state, self.episode_key = state, key
        if armed_now and self.trigger != "lockstep":
            # one zero at the arming: a bridge fed straight by this node (cmd_topic cmd, no mux) moves the machine
            # again after its start, a reconnection or a hold only once an all-zero command came (a review,
            # 2026-11-30: the first attempt after each stood still to its timeout). With a mux the zero is held
            # like every source while armed; the machine stands still while armed either way
            self.pub_cmd.publish(Float64MultiArray(data=list(ZERO_COMMAND)))
        if new_attempt:
            self.core.reset()
            self.attempts += 1
            self.last_decision = None
            self.get_logger().info(f"attempt {key} running: the {self.controller} commands")
        elif was and not self.running():
            self.pub_cmd.publish(Float64MultiArray(data=list(ZERO_COMMAND)))
            self.get_logger().info(f"attempt {key} {state or 'status lost'}: zero command sent, no motion until "
                                   "the next attempt runs")

    def _on_status(self, msg) -> None:
        self.status_watch.heard(time.monotonic())
        kv = {k.key: k.value for k in msg.values}
        state = kv.get("state", msg.message)
        self._lost.heard(state)              # not running: the publisher moved on, its next key-less running is new
        if state != RUNNING:
            self._lost_keys_heard.discard(None)
        self._set_episode(kv.get("state", msg.message), kv.get("episode"))
        self._hold_attempt_slope(kv)
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

    def _check_status_publisher(self, period: float) -> None:
        """The sim node or supervisor gone (crashed, stopped) while its last status said running:
        nobody says an attempt runs any more. Judged only once the publisher has been seen in
        the graph (a status that arrived before discovery caught up is no loss). A publisher that
        is still in the graph but silent (hung, SIGSTOP, a crashed process whose DDS lease has not
        expired yet: about 20 s) is found by the status' age: a running status older than
        status_timeout ends the attempt, for good (`_lost`). This node's own pause does not
        count (policy/status_watch.py): a check more than 3 periods + 50 ms after the previous one
        ends a pause, and the status' age counts from then at the earliest."""
        age = self.status_watch.age(time.monotonic(), 3.0 * period + 0.05)
        if self.running() and self.status_timeout > 0.0 and age is not None and age > self.status_timeout:
            self.get_logger().error(f"no {self.episode_topic} status for {age:.1f} s of this node's running time "
                                    f"(status_timeout {self.status_timeout:g} s): the supervisor or sim node stopped "
                                    f"or hung; attempt {self.episode_key} has ended for this node")
            self._lost.lose(self.episode_key)
            self._set_episode("lost", self.episode_key)
            self._hold_attempt_slope({})
            return
        if self.episode_state is None:
            return
        n = self.count_publishers(self.episode_topic)
        if n > 0:
            self._status_publisher_seen = True
        elif self._status_publisher_seen:
            self.get_logger().warn(f"no publisher of {self.episode_topic} any more: no attempt running")
            self._status_publisher_seen = False
            self._set_episode(None, None)
            self._hold_attempt_slope({})      # nobody runs an attempt: the live slope and end zone again

    # ------------------------------------------------------------------ decisions
    def _maybe_lockstep(self) -> None:
        if self.trigger != "lockstep":
            return
        t = self._stamps["joints"]
        if t is None or self._stamps["odom"] != t or self._status_stamp != t or t == self._decided_stamp:
            return
        if self._cycle(lockstep=True, why="lockstep"):
            self._decided_stamp = t          # one decision per state (the sim node may repeat one)

    def _on_fresh_odom(self) -> None:
        """Trigger odom: decide now, unless the last decision is less than 1/rate_hz -
        odom_margin old (at most rate_hz decisions a second)."""
        now = time.monotonic()
        if not self.running():
            return
        if self._last_decision_t is not None and now - self._last_decision_t < 1.0 / self.rate_hz - self.odom_margin:
            self.odom_skipped += 1
            return
        self._decide_at(now, "odom")

    def _decide_at(self, now: float, why: str) -> None:
        if self._last_decision_t is not None and self._last_why != "start":
            self.periods_ms.append((now - self._last_decision_t) * 1000.0)
        self._last_decision_t = now
        self._decided_mono_ns = int(now * 1e9)     # the decision's own time, for the trace
        self._last_why = why
        if why == "odom":
            self.odom_decisions += 1
        elif why == "fallback":
            self.fallback_decisions += 1
        self._cycle(why=why)

    def _on_fallback_check(self) -> None:
        """Trigger odom: the fallback (module docstring). Half a check period of tolerance keeps
        the fallback's own decisions at rate_hz. An attempt that begins counts as an
        odometry-triggered decision then (the odometry gets its 1.5 periods first)."""
        now = time.monotonic()
        self._check_status_publisher(1.0 / (self.rate_hz * FALLBACK_CHECKS))
        if not self.running():
            self._last_decision_t = self._last_why = None
            return
        if self._last_decision_t is None:
            self._last_decision_t, self._last_why = now, "start"
            return
        period = 1.0 / self.rate_hz
        limit = period * (1.0 if self._last_why == "fallback" else FALLBACK_AFTER_ODOM) - 0.5 * period / FALLBACK_CHECKS
        if now - self._last_decision_t >= limit:
            self._decide_at(now, "fallback")

    def _on_timer(self) -> None:
        now = time.monotonic()
        self._check_status_publisher(1.0 / self.rate_hz)
        if self._last_tick is not None:
            self.periods_ms.append((now - self._last_tick) * 1000.0)
        self._last_tick = now
        self._cycle()

    def _cycle(self, lockstep: bool = False, why: str = "timer") -> bool:
        """Decide and publish; returns False when a lockstep state was left undecided (inputs
        not all received yet: the sim node repeats its state, and a zero command would step it)."""
        t0 = time.perf_counter()
        if not self.running():    # no attempt running: silence (the zero went out on the transition)
            return True
        # Lockstep: the decision waits for joints, odometry and the status (drift, slope, end
        # zone) of one stamp, so every input is of exactly this state however long ago one of
        # them arrived (the sim node repeats a state whose first copy went unheard, and is paused
        # meanwhile); a wall-clock age would only turn a slow start into a spurious zero command
        # that steps the simulator. Only "never received" counts there.
        if lockstep:
            d = self.core.decide(self.inputs, time.monotonic(), math.inf)
        else:
            d = self.core.decide(self.inputs, time.monotonic(), self.input_timeout, self.slow_timeouts)
        if lockstep and d.reason and d.kind != "no_actor" and self.inputs.missing():
            self.get_logger().info(f"waiting for inputs: {d.reason}", throttle_duration_sec=2.0)
            return False
        self.pub_cmd.publish(Float64MultiArray(data=list(d.command)))
        sent_ns = time.monotonic_ns()
        self.last_decision = d
        if not d.reason:   # latency: inputs -> observation -> actor -> command published
            self.latencies_ms.append((time.perf_counter() - t0) * 1000.0)
        if d.observation is not None:   # for debugging, after the command
            self.pub_obs.publish(Float32MultiArray(data=d.observation.tolist()))
        self._publish_decision(d, why, sent_ns)
        self.cycles += 1
        if d.reason:
            self.zero_cycles += 1
            if d.kind in ERROR_KINDS:     # rclpy: one severity per call site
                self.get_logger().error(f"zero command: {d.reason}", throttle_duration_sec=2.0)
            else:
                self.get_logger().warn(f"zero command: {d.reason}", throttle_duration_sec=2.0)
        return True

    def _publish_decision(self, d, why: str, sent_ns: int) -> None:
        """The decision trace (module docstring), after the command."""
        st = DiagnosticStatus(name="lhd_policy: decision", message=why, hardware_id=self.policy_path)
        odom = self._stamps["odom"]
        values = {"odom_stamp_ns": str(odom if odom is not None else 0), "mono_ns": str(sent_ns),
                  # trigger odom: when the decision was taken (the clock its rate limit and
                  # fallback run on); mono_ns is when its command left, later by the cycle's work
                  "decided_mono_ns": str(self._decided_mono_ns if self.trigger == "odom" and self._decided_mono_ns
                                         is not None else sent_ns),
                  "command": ",".join(repr(float(v)) for v in d.command), "reason": d.reason or "",
                  # the observation the actor saw (task.observation.OBS_NAMES order, normalised), empty
                  # when none was built: what a replay compares with the truth
                  "observation": "" if d.observation is None else ",".join(f"{float(v):.6g}" for v in d.observation)}
        st.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        self.pub_decision.publish(st)

    def stop_commanding(self) -> None:
        """On the way out (Ctrl-C, SIGTERM): in timer (and odom) mode one last zero command, so that a
        machine holding its last command (sample-and-hold) stops now rather than at its command
        timeout. Not in lockstep mode, where every command steps the simulator."""
        if self.trigger in ("timer", "odom") and self.context.ok():
            self.pub_cmd.publish(Float64MultiArray(data=list(ZERO_COMMAND)))
            # a reliable writer destroyed right after a write may drop it: wait for the acks
            acked = self.pub_cmd.wait_for_all_acked(Duration(seconds=0.5))
            self.get_logger().info("stopping: sent a zero command" + ("" if acked else " (not acknowledged in 0.5 s)"))

    # ------------------------------------------------------------------ diagnostics
    def stats(self) -> dict:
        lat = np.array(self.latencies_ms) if self.latencies_ms else np.array([math.nan])
        per = np.array(self.periods_ms) if self.periods_ms else np.array([math.nan])
        jit = np.abs(per - 1000.0 / self.rate_hz)
        out = {"cycles": self.cycles, "zero_cycles": self.zero_cycles,
                "latency_p50_ms": float(np.percentile(lat, 50)), "latency_p99_ms": float(np.percentile(lat, 99)),
                "jitter_p99_ms": float(np.percentile(jit, 99))}
        if self.trigger == "odom":
            out.update(odom_decisions=self.odom_decisions, fallback_decisions=self.fallback_decisions,
                       odom_skipped=self.odom_skipped)
        return out

    def _diag_controller(self):
        if self.controller == "tampier":
            c = self.core.controller
            return OK, f"Tampier-style heuristic, stage {c.stage}", {"path": self.policy_path, "stage": c.stage,
                                                                      "attempts": self.attempts}
        if self.controller == "teacher":
            st = self.core.setting
            return OK, f"demonstrations' teacher, stage {self.core.stage}", {
                "path": self.policy_path, "stage": self.core.stage, "crowd": st.crowd, "pre_curl_rad": st.pre_curl,
                "end_zone_stop_m": st.end_zone_stop, "drift_confirm": self.core.drift_confirm,
                "attempts": self.attempts}
        if self.core.actor is None:
            return ERROR, f"no actor loaded from {self.policy_path}: zero commands only", {}
        lo, hi = self.core.slope_range_deg
        return OK, f"{self.core.variant.upper()} actor loaded", {"path": self.policy_path, "trained_slope_deg": f"{lo:g}-{hi:g}"}

    def _diag_inputs(self):
        now = time.monotonic()
        values = {name: (f"{now - self.inputs.arrival[name]:.2f} s old" if name in self.inputs.values else "missing")
                  for name in INPUTS}
        slope = self.inputs.values.get("slope")
        refusal = ""
        if slope is not None:
            values["slope_deg"] = math.degrees(slope)
            refusal = self.core.slope_refusal(slope)
        if refusal:
            return ERROR, refusal, values
        if self.trigger == "lockstep":     # lockstep judges no ages (docs/ros_nodes.md)
            bad = self.inputs.problems(now, math.inf)
        else:
            bad = self.inputs.problems(now, self.input_timeout, self.slow_timeouts)
        if bad:
            return WARN, "; ".join(bad), values
        return OK, "all inputs fresh", values

    def _diag_decision(self):
        values = {**self.stats(), "episode_state": str(self.episode_state), "episode": str(self.episode_key)}
        if self.episode_state is None:
            return WARN, NO_PUBLISHER, values
        if not self.running():
            return OK, f"attempt {self.episode_state}: waiting to be armed", values
        d = self.last_decision
        if d is None:
            return WARN, "no decision yet", values
        if d.reason:
            return (ERROR if d.kind in ERROR_KINDS else WARN), f"zero command: {d.reason}", values
        return OK, f"{self.controller} commanding" + (f" ({d.note})" if d.note else ""), values


def main(args=None) -> int:
    return run_node(PolicyNode, "lhd_policy", args, before_destroy=lambda n: n.stop_commanding())


if __name__ == "__main__":
    raise SystemExit(main())
