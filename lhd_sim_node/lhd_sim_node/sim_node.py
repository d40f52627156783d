"""`ros2 run lhd_sim_node sim_node`: the MuJoCo LHD and its FEE pile behind the topic contract.

Publishes (namespace_prefix, default /lhd; under `-r __ns:=/lhd2` the namespace instead), in
this order after every control period:
  clock                         rosgraph_msgs/Clock         sim time; relative name: /clock in the root
                                namespace, /lhd2/clock under /lhd2
  /lhd/pile/slope               std_msgs/Float64            alpha, rad (truth); latched
  /lhd/pile/end_zone            std_msgs/Float64MultiArray  [x_min, x_max, z_min] m (truth); latched
  /lhd/pile/zones               std_msgs/Float64MultiArray  all 8 limits of task.zones.Zones (as_list
                                order), as the end-zone node publishes them on the machine; latched
  /lhd/wheel_drift/front, /rear, /lhd/wheel_drift           std_msgs/Bool
  /lhd/episode                  diagnostic_msgs/DiagnosticStatus  state, episode, step, loaded
                                mass, outcome and reason, stamp_ns of the state it describes
  /lhd/odom                     nav_msgs/Odometry           base_link pose in the pile frame,
                                twist.linear.x = v_x (forward speed along the pile's x axis)
  /lhd/joint_states             sensor_msgs/JointState      boom, bucket, articulation (position,
                                velocity), wheels (velocity)
and /diagnostics (episode, commands, real time) every second.
Subscribes /lhd/cmd (std_msgs/Float64MultiArray [u_wheels, u_boom, u_bucket] rad/s).
Service ~/reset (std_srvs/Trigger): a new episode now.

Modes (parameter `mode`):
  realtime  physics on the wall clock (steady timer), one control period per 1/frequency s;
            an episode's physics starts at its first command (until then the initial state
            is repeated at the control rate and no simulated time passes); the latest command
            is held; a command older than cmd_timeout (0.3 s) brakes the wheels and holds the
            arm (zero speeds), with a throttled warning.
  lockstep  exactly one control period per received command; deterministic; as fast as the
            policy answers. The stamps of /lhd/odom, /lhd/joint_states and /lhd/episode
            name the state, so a subscriber can wait for a complete set. With auto_reset, the
            next episode starts on the controller's answer to the ended state (the policy node's
            zero command), which is not a control period of the new episode; a controller that
            does not answer an ended state gets the next episode after LOCKSTEP_ACK_WAIT_S.
            (Until 2026-11-28 the next episode started at once and that answer drove its first
            period: every command of episodes 1, 2, ... ran one period late.)
Episodes: episode k uses seed `seed + k` and the slope / material parameters (negative slope
or "random": drawn by the simulator; `slopes_deg` "15,20,25,30" cycles through a list), like
LhdLoadingEnv.reset(seed=seed + k, options={"slope_deg": ..., "material": ...}). slope_deg,
slopes_deg, material, auto_reset, reset_delay and cmd_timeout may change at run time
(`ros2 param set`); the others are read-only (docs/ros_nodes.md).
"""
from __future__ import annotations

import json
import math
import threading
import time

import mujoco
import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from rclpy.parameter import Parameter
from std_msgs.msg import Bool, Float64, Float64MultiArray, MultiArrayDimension
from std_srvs.srv import Trigger

from lhd_loading_ros.task import transition
from lhd_loading_ros.task.metrics import SL_BANDS
from lhd_loading_ros.task.config import config_hash, load_config, task_hash
from lhd_loading_ros.ros.qos import COMMAND_QOS, LATCHED_QOS, MEASUREMENT_QOS, STATUS_QOS
from lhd_loading_ros.ros.diagnostics import OK, WARN, Diagnostics
from lhd_loading_ros.ros.params import Param, Params, steady_timer, topic_prefix
from lhd_loading_ros.ros.run import run_node

from .env import ATTACK_REDRAWS, LhdLoadingEnv, reset_or_redraw, warm_up
from .ros_env import UNKNOWN_NODE_NAME
from .simulator import MATERIALS, AttackError, SimulationError

# QoS (lhd_loading_ros.ros.qos, shared with the hardware bridge and the policy node): measurements
# MEASUREMENT_QOS (reliable, keep-last 5: lockstep must not lose a state, and best-effort
# subscribers still match), commands COMMAND_QOS (keep-last 1), episode status STATUS_QOS
# (transient local: a launcher that starts late still sees it). /clock: reliable keep-last 1.
CLOCK_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
MODES = ("realtime", "lockstep")
LOCKSTEP_ACK_WAIT_S = 1.0    # lockstep auto-reset: how long an ended episode waits for the controller's answer
EXIT_DELAY_S = 1.0           # exit_when_done: how long the last ended state stays published before the node exits
JOINTS = ("boom", "bucket", "articulation", "wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr")


def ns_time(t_ns: int):
    from builtin_interfaces.msg import Time

    return Time(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000)


class SimNode(Node):
    def __init__(self, stop: threading.Event | None = None, **node_kwargs):
        super().__init__("lhd_sim", **node_kwargs)
        self._stop = stop    # set by exit_when_done once every episode is done (run_node then returns 0)
        # the parameter file first: it gives the defaults and ranges of the others
        cfg = load_config(Params(self, [Param("config", "", "lhd_params.yaml to use; empty: found automatically "
                                                "(LHD_CONFIG, then the package's)")])["config"] or None)
        self.alpha_range_deg = (cfg["paper"]["episode"]["alpha_min_deg"], cfg["paper"]["episode"]["alpha_max_deg"])
        lo, hi = self.alpha_range_deg
        self.slopes: list[float] = []
        self.slope_deg: float | None = None
        self.params = Params(self, [
            Param("mode", "realtime", "realtime: physics on the wall clock, sample-and-hold; lockstep: one control "
                  "period per received command", choices=MODES),
            Param("seed", 0, "episode k uses seed + k", lo=0, hi=2**31 - 1),
            Param("slopes_deg", "", f"slopes to cycle through, degrees in [{lo:g}, {hi:g}] ('15,20,25,30', a list or "
                  "one number; empty: use slope_deg); a change applies from the next episode", dynamic_type=True,
                  check=self._check_slopes, on_change=self._set_slopes),
            Param("slope_deg", -1.0, f"pile slope, degrees in [{lo:g}, {hi:g}]; negative: random per episode; a "
                  "change applies from the next episode", check=self._check_slope, on_change=self._set_slope),
            Param("material", "random", "pile material (random: drawn per episode); a change applies from the next "
                  "episode", choices=(*MATERIALS, "random"), on_change=self._set_material),
            Param("episodes", 0, "episodes to run before stopping auto-reset (0: no limit)", lo=0, hi=10**9),
            Param("exit_when_done", False, f"exit (status 0) {EXIT_DELAY_S:g} s after the last of `episodes` ended, "
                  "its state and result published: sim_loading.launch.py then ends the launch, as `lhd up sim` "
                  "ends after --episodes; with auto_reset false also after an aborted episode; needs episodes > 0"),
            Param("auto_reset", True, "start the next episode by itself (after reset_delay in realtime mode)",
                  on_change=self._set_auto_reset),
            Param("reset_delay", 1.0, "s between the end of an episode and the next one (realtime mode)",
                  lo=0.0, hi=60.0, on_change=lambda v: setattr(self, "reset_delay", v)),
            Param("cmd_timeout", float(cfg["hardware"]["cmd_timeout"]), "s: a command older than this brakes the "
                  "wheels and holds the arm (realtime mode)", lo=0.01, hi=10.0,
                  on_change=lambda v: setattr(self, "cmd_timeout", v)),
            Param("namespace_prefix", "/lhd", "topic prefix in the root namespace (under a namespace, the "
                  "namespace is the prefix)"),
            Param("frame_id", "pile", "frame of /odom's pose"),
            Param("base_frame_id", "base_link", "child frame of /odom"),
            Param("publish_transitions", True, "publish <prefix>/rl/transition (observation, reward, end flags) "
                  "after every state, for learners (lhd_sim_node.ros_env)"),
            Param("next_seed", -1, "seed of the next episode only (a learner's reset(seed=...)); -1: seed + "
                  "episode index", lo=-1, hi=2**31 - 1, on_change=lambda v: setattr(self, "next_seed", v),
                  log_change=False),
        ])
        gp = self.params.__getitem__
        self._set_slopes(gp("slopes_deg"))
        self._set_slope(gp("slope_deg"))
        if self.slopes and self.slope_deg is not None:     # the checks above ran before both were known
            raise ValueError(f"parameter 'slope_deg' = {self.slope_deg:g} is invalid: slopes_deg = {self.slopes} "
                             "is set too; give one of the two")
        self.mode = gp("mode")
        self.seed = gp("seed")
        self.episodes_max = gp("episodes")
        self.exit_when_done = gp("exit_when_done")
        if self.exit_when_done and self.episodes_max == 0:
            raise ValueError("parameter 'exit_when_done' = true needs episodes > 0 (the node would never exit); "
                             "expected episodes:=N with N >= 1, or exit_when_done:=false")
        self.material = None if gp("material") == "random" else gp("material")
        self.cmd_timeout = gp("cmd_timeout")
        self.reset_delay = gp("reset_delay")
        self.auto_reset = gp("auto_reset")
        self.frame_id, self.base_frame_id = gp("frame_id"), gp("base_frame_id")
        self.next_seed = gp("next_seed")
        self.config_hash = config_hash(cfg)
        self.task_hash = task_hash(cfg)   # the reward's settings too (a learner checks both)
        ns = topic_prefix(self, gp("namespace_prefix"))

        # stepped with actuator commands (the variant is not used). It publishes the pile's own zones (the truth, as
        # the topic contract says), so the end-zone node's nominal-density zones are never its episodes' judge,
        # whatever randomization.zones_at_nominal_density says (`lhd train --env ros` refuses the key)
        self.env = LhdLoadingEnv("rld", cfg, zones_nominal_density=False)
        self.sim = self.env.sim
        # the compiled physics before the first status (env.warm_up): a fresh install's first step compiled
        # for seconds while the episode said running, and the policy node gave attempt 0 up
        took = warm_up(self.env, self.seed)
        if took > 1.0:
            self.get_logger().info(f"physics ready in {took:.1f} s (compiled on the first run after an install, "
                                   "then loaded from numba's cache)")
        self.dt = self.env.p.control_dt
        self.dt_ns = int(round(self.dt * 1e9))
        m = self.sim.model
        # the articulation is rigid in the model (mjcf.py): reported, as a steady 0, where a
        # machine's encoder would report it
        art = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "articulation")
        self._art_q = int(m.jnt_qposadr[art]) if art >= 0 else None
        self._art_v = int(m.jnt_dofadr[art]) if art >= 0 else None
        self._wheel_q = [m.jnt_qposadr[m.joint(w).id] for w in JOINTS[3:]]
        self._wheel_v = [m.jnt_dofadr[m.joint(w).id] for w in JOINTS[3:]]

        # relative name: /clock in the root namespace, <ns>/clock under a namespace, so that two
        # simulators on one domain do not both drive /clock (a namespaced consumer with
        # use_sim_time remaps: -r /clock:=<ns>/clock)
        self.pub_clock = self.create_publisher(Clock, "clock", CLOCK_QOS)
        # slope and end zone change once per episode: latched, like a surveyed constant
        self.pub_slope = self.create_publisher(Float64, f"{ns}/pile/slope", LATCHED_QOS)
        self.pub_zone = self.create_publisher(Float64MultiArray, f"{ns}/pile/end_zone", LATCHED_QOS)
        self.pub_zones = self.create_publisher(Float64MultiArray, f"{ns}/pile/zones", LATCHED_QOS)
        self.pub_front = self.create_publisher(Bool, f"{ns}/wheel_drift/front", MEASUREMENT_QOS)
        self.pub_rear = self.create_publisher(Bool, f"{ns}/wheel_drift/rear", MEASUREMENT_QOS)
        self.pub_drift = self.create_publisher(Bool, f"{ns}/wheel_drift", MEASUREMENT_QOS)
        self.pub_status = self.create_publisher(DiagnosticStatus, f"{ns}/episode", STATUS_QOS)
        self.pub_odom = self.create_publisher(Odometry, f"{ns}/odom", MEASUREMENT_QOS)
        self.pub_js = self.create_publisher(JointState, f"{ns}/joint_states", MEASUREMENT_QOS)
        self.pub_transition = (self.create_publisher(Float64MultiArray, f"{ns}/rl/transition", MEASUREMENT_QOS)
                               if gp("publish_transitions") else None)
        self.create_subscription(Float64MultiArray, f"{ns}/cmd", self._on_cmd, COMMAND_QOS)
        self._cmd_topic = f"{ns}/cmd"
        self.create_service(Trigger, "~/reset", self._on_reset)
        # who publishes on /cmd, as this node's DDS participant knows it (a learner asks before it takes the
        # node: a participant of its own, just started, may not have discovered the others yet)
        self.create_service(Trigger, "~/cmd_publishers", self._on_cmd_publishers)

        self.t_ns = 0                    # sim time, never goes back (across episodes too)
        self.episode = -1
        self._zones_sent = None
        self.episodes_done = 0
        self.outcome = "running"
        self.abort_reason = ""
        self.result = None
        self.episode_seed = self.seed
        self._obs, self._reward, self._term, self._trunc = None, 0.0, False, False
        self._applied = np.zeros(3)      # the command the last step was taken with (for learners)
        self._cmd = np.zeros(3)
        self._cmd_time = None            # monotonic arrival time of the latest valid command
        self._started = False            # realtime: physics runs from the episode's first command on
        self._ended_at = None            # monotonic time the episode ended (realtime auto-reset)
        self._awaiting_ack = False       # lockstep auto-reset: the ended state's answer starts the next episode
        self.rejected = 0
        self.last_rejection = ""
        self.stale_stops = 0
        self.overruns = 0                # realtime ticks later than 1.5 control periods after the previous
        self._last_tick = None
        self._last_publish = 0.0
        self._window = {"t": time.monotonic(), "sim_ns": 0, "rejected": 0, "stale": 0, "overruns": 0}
        self._new_episode()
        # the steady clock: with use_sim_time the node's clock is the /clock this node publishes,
        # and a timer on it would wait on itself
        if self.mode == "realtime":
            steady_timer(self, self.dt, self._tick_realtime)
        else:
            # lockstep waits for a command; a subscriber that joined late (or lost a message)
            # would wait for a state: repeat the current one (same stamp) while nothing happens
            steady_timer(self, 0.5, self._repeat_state)
        self.diagnostics = Diagnostics(self, {"episode": self._diag_episode, "commands": self._diag_commands,
                                              "real time": self._diag_realtime}, hardware_id="mujoco")
        self.get_logger().info(f"sim node up: mode {self.mode}, seed {self.seed}, slope "
                               f"{self._slope_text()}, material {gp('material')}, topics under {ns}")

    # ------------------------------------------------------------------ parameters
    @staticmethod
    def _parse_slopes(value) -> list[float]:
        if isinstance(value, (list, tuple)):
            value = ",".join(str(v) for v in value)
        text = str(value).strip()
        return [float(v) for v in text.split(",")] if text else []

    def _check_slopes(self, value) -> str | None:
        lo, hi = self.alpha_range_deg
        try:
            vals = self._parse_slopes(value)
        except ValueError:
            return "expected comma-separated degrees such as '15,20,25,30'"
        bad = [v for v in vals if not (lo <= v <= hi)]
        if bad:
            return f"{bad} out of range; expected degrees in [{lo:g}, {hi:g}]"
        if vals and self.slope_deg is not None:
            return f"slope_deg = {self.slope_deg:g} is set too; set slope_deg to -1 first (one of the two)"
        return None

    def _check_slope(self, value: float) -> str | None:
        lo, hi = self.alpha_range_deg
        if value >= 0 and not (lo <= value <= hi):
            return f"out of range; expected degrees in [{lo:g}, {hi:g}], or negative for a random slope"
        if value >= 0 and self.slopes:
            return f"slopes_deg = {self.slopes} is set and would take precedence; clear slopes_deg first"
        return None

    def _set_slopes(self, value) -> None:
        self.slopes = self._parse_slopes(value)

    def _set_slope(self, value: float) -> None:
        self.slope_deg = value if value >= 0 else None

    def _set_material(self, value: str) -> None:
        self.material = None if value == "random" else value

    def _set_auto_reset(self, value: bool) -> None:
        self.auto_reset = value
        if not value:
            self._awaiting_ack = False
        if value and self.mode == "lockstep" and self.outcome != "running" and not self._finished_all():
            self._new_episode()       # realtime: the loop sees the flag at its next tick

    def _slope_text(self) -> str:
        return str(self.slopes) if self.slopes else ("random" if self.slope_deg is None else f"{self.slope_deg:g}")

    # ------------------------------------------------------------------ episodes
    def _new_episode(self) -> None:
        self.episode += 1
        opts = {}
        if self.slopes:          # slopes_deg cycles: episode k on slopes[k % n]
            opts["slope_deg"] = self.slopes[self.episode % len(self.slopes)]
        elif self.slope_deg is not None:
            opts["slope_deg"] = self.slope_deg
        if self.material is not None:
            opts["material"] = self.material
        self.episode_seed = self.seed + self.episode
        if self.next_seed >= 0:       # a learner's reset(seed=...): this episode only
            self.episode_seed, self.next_seed = self.next_seed, -1
            self.set_parameters([Parameter("next_seed", value=-1)])
        try:
            self._obs = reset_or_redraw(self.env, self.episode_seed, opts, self.get_logger().warn)
        except (AttackError, SimulationError) as e:
            # no pile of this episode's conditions could be set up, nor any of its redraws: the
            # parameters cannot work (an attack too short or too slow for the pile); the node ends
            # with the reason (run_node: exit status 2), not a traceback, and nothing moves
            raise ValueError(
                f"episode {self.episode} (seed {self.episode_seed}, slope {opts.get('slope_deg', 'random')}): cannot "
                f"set up the pile: {e}; {ATTACK_REDRAWS} redraws of the pile failed too. Expected sim.attack_timeout, "
                "sim.attack_speed_min_fraction and paper.episode.d_init (the parameter file) that let the attack drive "
                "bury the bucket in the pile"
            ) from e
        self._reward, self._term, self._trunc = 0.0, False, False
        self._applied = np.zeros(3)
        self.outcome, self.result, self._ended_at = "running", None, None
        self._awaiting_ack = False
        self._cmd[:] = 0.0
        self._cmd_time = None
        self._started = False
        if self.episode > 0:
            self.t_ns += self.dt_ns      # a fresh stamp for the new episode's first state
        self.publish_state()

    def _finished_all(self) -> bool:
        return self.episodes_max > 0 and self.episodes_done >= self.episodes_max

    def _on_reset(self, request, response):
        self._new_episode()
        response.success = True
        response.message = f"episode {self.episode} started (seed {self.episode_seed})"
        return response

    def _on_cmd_publishers(self, request, response):
        """Trigger: message = JSON list of {"node": "/ns/name" (null while DDS has not reported the
        node's name), "gid": hex of the endpoint's GID}, one per publisher on this node's /cmd."""
        out = []
        for info in self.get_publishers_info_by_topic(self._cmd_topic):
            named = info.node_name != UNKNOWN_NODE_NAME
            out.append({"node": f"{info.node_namespace.rstrip('/')}/{info.node_name}" if named else None,
                        "gid": bytes(info.endpoint_gid).hex()})
        response.success = True
        response.message = json.dumps(out)
        return response

    # ------------------------------------------------------------------ commands
    def _on_cmd(self, msg: Float64MultiArray) -> None:
        data = list(msg.data)
        if len(data) != 3 or not all(math.isfinite(v) for v in data):
            self.rejected += 1
            self.last_rejection = (f"rejected /cmd {data}: expected 3 finite values [u_wheels, u_boom, u_bucket] "
                                   "rad/s")
            self.get_logger().warn(self.last_rejection, throttle_duration_sec=1.0)
            return
        u = np.array(data)
        lo, hi = self._ranges()
        clipped = np.clip(u, lo, hi)
        if not np.array_equal(clipped, u):
            self.get_logger().warn(f"command {data} outside the actuator ranges {lo.tolist()}..{hi.tolist()} rad/s: "
                                   "clamped", throttle_duration_sec=1.0)
        self._cmd = clipped
        self._cmd_time = time.monotonic()
        self._started = True
        if self.mode == "lockstep" and self.outcome == "running":
            self._step(self._cmd)
        elif self.mode == "lockstep" and self._awaiting_ack:
            self._new_episode()      # the answer to the ended state: the next episode, no period stepped

    def _lockstep_next(self) -> None:
        """Lockstep auto-reset after an ended episode: wait for the controller's answer to the
        ended state (_on_cmd starts the next episode on it), or LOCKSTEP_ACK_WAIT_S (_repeat_state)."""
        if self.auto_reset and not self._finished_all():
            self._awaiting_ack = True

    def _exit_if_done(self, now: float) -> bool:
        """exit_when_done: once every episode is done and the last ended state has been out for
        EXIT_DELAY_S, ask run_node to stop (the node then exits 0). True when it asked."""
        # with auto_reset off an aborted episode (not counted) is followed by nothing either: exit then too
        done = self._finished_all() or (not self.auto_reset and self.outcome == "aborted")
        if (self.exit_when_done and done and self._ended_at is not None
                and now - self._ended_at >= EXIT_DELAY_S and self._stop is not None and not self._stop.is_set()):
            self.get_logger().info(f"all {self.episodes_max} episode(s) done: exiting (exit_when_done)" if self._finished_all()
                                   else f"episode {self.episode} aborted and auto_reset is off: exiting (exit_when_done)")
            self._stop.set()
            return True
        return False

    def _repeat_state(self) -> None:
        if self._exit_if_done(time.monotonic()):
            return
        if (self._awaiting_ack and self._ended_at is not None
                and time.monotonic() - self._ended_at >= LOCKSTEP_ACK_WAIT_S):
            self._new_episode()      # a controller that does not answer an ended state
            return
        if time.monotonic() - self._last_publish >= 0.5:
            self.publish_state()

    def _ranges(self):
        p = self.env.p
        return (np.array([p.wheels_min, p.boom_min, p.bucket_min]), np.array([p.wheels_max, p.boom_max, p.bucket_max]))

    def _tick_realtime(self) -> None:
        now = time.monotonic()
        if self._last_tick is not None and now - self._last_tick > 1.5 * self.dt:
            self.overruns += 1
        self._last_tick = now
        if self.outcome != "running":
            if self._exit_if_done(now):
                return
            if (self.auto_reset and not self._finished_all() and self._ended_at is not None
                    and now - self._ended_at >= self.reset_delay):
                self._new_episode()
            return
        if not self._started:
            # the episode starts when its controller does: until the first command the physics
            # holds the initial state (no simulated time passes) and the state is repeated at the
            # control rate, so a slow start of the controller does not count against the attempt
            self.publish_state()
            return
        if now - self._cmd_time > self.cmd_timeout:
            self.stale_stops += 1
            self.get_logger().warn(f"no /cmd for {self.cmd_timeout} s: wheels braked, arm held",
                                   throttle_duration_sec=2.0)
            u = np.zeros(3)
        else:
            u = self._cmd
        self._step(u)

    def _step(self, u: np.ndarray) -> None:
        try:
            self._obs, self._reward, term, trunc, info = self.env.step_actuator(u)
        except SimulationError as e:
            # MuJoCo reset an unstable state: the episode ends as aborted (no result, no reward), the
            # last good state is published once more, and the next episode starts as after any end
            self.outcome, self.result, self.abort_reason = "aborted", None, str(e)
            self._applied = np.zeros(3)
            self._term, self._trunc = True, False
            self._ended_at = time.monotonic()
            self.get_logger().error(f"episode {self.episode} aborted: {e}")
            self.publish_state()
            if self.mode == "lockstep":
                self._lockstep_next()
            return
        self._applied = np.array(u, dtype=np.float64)
        self._term, self._trunc = bool(term), bool(trunc)
        self.t_ns += self.dt_ns
        if term or trunc:
            self.outcome = info["outcome"] if term else "timeout"
            self.result = info["episode_result"]
            self.episodes_done += 1
            self._ended_at = time.monotonic()
            r = self.result
            self.get_logger().info(
                f"episode {self.episode} {self.outcome}{' (not a success)' if self._judgement() else ''}: loaded "
                f"{r.loaded:.1f} kg, SL {r.success_level}, {r.elapsed_s:.1f} s, drift front {r.front_drift_pct:.0f} % "
                f"rear {r.rear_drift_pct:.0f} %")
        self.publish_state()
        if self.outcome != "running" and self.mode == "lockstep":
            self._lockstep_next()    # realtime: after reset_delay, in _tick_realtime

    # ------------------------------------------------------------------ diagnostics
    def _since_last(self, **now_counts) -> dict:
        """Counts since the previous diagnostics report (each source is called once a period)."""
        out = {k: v - self._window[k] for k, v in now_counts.items()}
        self._window.update(now_counts)
        return out

    def _diag_episode(self):
        waiting = self.mode == "realtime" and self.outcome == "running" and not self._started
        msg = f"episode {self.episode} {self.outcome}" + (": waiting for the first /cmd" if waiting else "")
        if self._finished_all():
            msg += " (all episodes done)"
        return OK, msg, {"mode": self.mode, "episode": self.episode, "state": self.outcome, "step": self.env.steps,
                         "sim_time_s": self.t_ns / 1e9, "slope_deg": math.degrees(self.sim.pile.alpha),
                         "material": self.sim.material, "episodes_done": self.episodes_done,
                         "waiting_for_first_command": waiting}

    def _diag_commands(self):
        d = self._since_last(rejected=self.rejected, stale=self.stale_stops)
        values = {"rejected": self.rejected, "stale_stops": self.stale_stops, "cmd_timeout_s": self.cmd_timeout}
        if d["rejected"]:
            return WARN, f"{d['rejected']} command(s) rejected in the last period; last: {self.last_rejection}", values
        if d["stale"]:
            return WARN, f"no /cmd for {self.cmd_timeout} s: wheels braked, arm held", values
        return OK, "commands ok", values

    def _diag_realtime(self):
        now = time.monotonic()
        wall = now - self._window["t"]
        d = self._since_last(t=now, sim_ns=self.t_ns, overruns=self.overruns)
        rtf = d["sim_ns"] / 1e9 / wall if wall > 0 else 0.0
        values = {"real_time_factor": rtf, "overruns": self.overruns}
        if self.mode == "lockstep":
            return OK, "lockstep: paced by the controller", values
        if d["overruns"]:
            return WARN, f"{d['overruns']} control period(s) late by more than half a period in the last period " \
                         f"(real-time factor {rtf:.2f})", values
        return OK, f"real-time factor {rtf:.2f}", values

    # ------------------------------------------------------------------ publishing
    def _status(self) -> DiagnosticStatus:
        st = DiagnosticStatus()
        st.name = "lhd_sim/episode"
        st.hardware_id = "mujoco"
        # state "success" is the episode's end in the end zone (the task's term, as the supervisor's);
        # the paper's success also needs the load and the final pitch (success_level >= 1): an end
        # zone reached with 2 kg is said to be no success, at WARN (a review, 2026-11-28)
        st.message = self.outcome + self._judgement() + (" (all episodes done)" if self._finished_all() else "")
        st.level = (DiagnosticStatus.OK if self.outcome == "running" or (self.outcome == "success" and self.result is not None
                                                                          and self.result.success)
                    else DiagnosticStatus.WARN)
        s = self.env.state
        vals = {
            "state": self.outcome, "episode": self.episode, "seed": self.episode_seed,
            "config_hash": self.config_hash, "task_hash": self.task_hash,
            "step": self.env.steps, "stamp_ns": self.t_ns, "loaded_mass": f"{self.sim.loaded_mass:.4f}",
            "slope_deg": f"{math.degrees(self.sim.pile.alpha):.3f}", "material": self.sim.material,
            "x_shovel": f"{s.x_shovel:.4f}", "z_shovel": f"{s.z_shovel:.4f}",
            "episodes_done": self.episodes_done, "all_done": self._finished_all(),
            # the unstamped inputs of this very state, exact (repr), for lockstep subscribers:
            # separate topics give no ordering guarantee against the stamped ones
            "drift_front": bool(s.drift_front), "drift_rear": bool(s.drift_rear),
            "slope_rad": repr(float(self.sim.pile.alpha)),
            "end_zone": ",".join(repr(float(v)) for v in (self.sim.zones.x_min, self.sim.zones.x_max, self.sim.zones.z_min)),
        }
        if self.outcome == "aborted":
            vals["reason"] = self.abort_reason
        if self.result is not None:
            r = self.result
            vals.update({"success": r.success, "success_level": r.success_level, "return": f"{r.ret:.3f}",
                         "elapsed_s": f"{r.elapsed_s:.2f}", "front_drift_pct": f"{r.front_drift_pct:.2f}",
                         "rear_drift_pct": f"{r.rear_drift_pct:.2f}", "phi_final_deg": f"{math.degrees(r.phi_final):.2f}",
                         "max_tilt_deg": f"{r.max_tilt_deg:.3f}",
                         "reason": {"success": "bucket tip reached the end zone",
                                    "failure": "bucket tip entered the restricted zone",
                                    "timeout": f"{self.env.p.max_steps} control steps passed"}[self.outcome]
                         + self._judgement()})
        st.values = [KeyValue(key=k, value=str(v)) for k, v in vals.items()]
        return st

    def _judgement(self) -> str:
        """For an end in the end zone (or at the timeout) that fails the paper's success test: why."""
        r = self.result
        if r is None or r.success or self.outcome not in ("success", "timeout"):
            return ""
        return (f"; not a success: SL {r.success_level}, {r.loaded:.1f} kg, final pitch {math.degrees(r.phi_final):.1f} "
                f"deg (the paper's success needs at least {SL_BANDS[-1][0]:g} kg and a final pitch above "
                f"{math.degrees(self.env.p.phi_thresh_pitch):.0f} deg)")

    def publish_state(self) -> None:
        self._last_publish = time.monotonic()
        stamp = ns_time(self.t_ns)
        d = self.sim.data
        s = self.env.state
        self.pub_clock.publish(Clock(clock=stamp))
        self.pub_slope.publish(Float64(data=float(self.sim.pile.alpha)))
        z = self.sim.zones
        self.pub_zone.publish(Float64MultiArray(data=[float(z.x_min), float(z.x_max), float(z.z_min)]))
        if self._zones_sent is not z:     # once per episode (the object changes with the pile)
            self.pub_zones.publish(Float64MultiArray(data=z.as_list()))
            self._zones_sent = z
        self.pub_front.publish(Bool(data=bool(s.drift_front)))
        self.pub_rear.publish(Bool(data=bool(s.drift_rear)))
        self.pub_drift.publish(Bool(data=bool(s.drift)))
        self.pub_status.publish(self._status())
        od = Odometry()
        od.header.stamp = stamp
        od.header.frame_id = self.frame_id
        od.child_frame_id = self.base_frame_id
        q = d.qpos
        od.pose.pose.position.x, od.pose.pose.position.y, od.pose.pose.position.z = (float(q[0]), float(q[1]), float(q[2]))
        o = od.pose.pose.orientation
        o.w, o.x, o.y, o.z = (float(q[3]), float(q[4]), float(q[5]), float(q[6]))
        od.twist.twist.linear.x = float(s.v_x)
        od.twist.twist.angular.z = float(d.qvel[5])
        self.pub_odom.publish(od)
        js = JointState()
        js.header.stamp = stamp
        js.name = list(JOINTS)
        art_q = 0.0 if self._art_q is None else float(q[self._art_q])
        art_v = 0.0 if self._art_v is None else float(d.qvel[self._art_v])
        m = self.env.measured_state      # the arm as its sensors read it (an episode's drawn offsets, sampled rates)
        js.position = [float(m.phi_boom), float(m.phi_bucket), art_q] + [float(q[i]) for i in self._wheel_q]
        js.velocity = ([float(m.dphi_boom), float(m.dphi_bucket), art_v]
                       + [float(d.qvel[i]) for i in self._wheel_v])
        self.pub_js.publish(js)
        if self.pub_transition is not None:
            msg = Float64MultiArray(data=transition.encode(self.episode, self.episode_seed, self.env.steps, self.t_ns,
                                                           self._reward, self._term, self._trunc, self._obs,
                                                           self._applied))
            msg.layout.dim = [MultiArrayDimension(label=transition.LABEL, size=transition.SIZE, stride=transition.SIZE)]
            self.pub_transition.publish(msg)


def main(args=None) -> int:
    stop = threading.Event()
    return run_node(lambda: SimNode(stop=stop), "lhd_sim", args, stop=stop)


if __name__ == "__main__":
    raise SystemExit(main())
