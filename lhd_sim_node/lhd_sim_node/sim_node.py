"""`ros2 run lhd_sim_node sim_node`: the MuJoCo LHD and its FEE pile behind the topic contract.

Publishes (namespace_prefix, default /lhd), in this order after every control period:
  /clock                        rosgraph_msgs/Clock         sim time (nodes run with use_sim_time)
  /lhd/pile/slope               std_msgs/Float64            alpha, rad (truth)
  /lhd/pile/end_zone            std_msgs/Float64MultiArray  [x_min, x_max, z_min] m (truth)
  /lhd/wheel_drift/front, /rear, /lhd/wheel_drift           std_msgs/Bool
  /lhd/episode                  diagnostic_msgs/DiagnosticStatus  state, episode, step, loaded
                                mass, outcome and reason, stamp_ns of the state it describes
  /lhd/odom                     nav_msgs/Odometry           base_link pose in the pile frame,
                                twist.linear.x = v_x (forward speed along the pile's x axis)
  /lhd/joint_states             sensor_msgs/JointState      boom, bucket, articulation (position,
                                velocity), wheels (velocity)
Subscribes /lhd/cmd (std_msgs/Float64MultiArray [u_wheels, u_boom, u_bucket] rad/s).
Service ~/reset (std_srvs/Trigger): a new episode now.

Modes (parameter `mode`):
  realtime  physics on the wall clock, one control period per 1/frequency s; the latest
            command is held; a command older than cmd_timeout (0.3 s) brakes the wheels and
            holds the arm (zero speeds), with a throttled warning.
  lockstep  exactly one control period per received command; deterministic; as fast as the
            policy answers. The stamps of /lhd/odom, /lhd/joint_states and /lhd/episode
            name the state, so a subscriber can wait for a complete set.
Episodes: episode k uses seed `seed + k` and the slope / material parameters (negative slope
or "random": drawn by the simulator; `slopes_deg` "15,20,25,30" cycles through a list), like
LhdLoadingEnv.reset(seed=seed + k, options={"slope_deg": ..., "material": ...}).
"""
from __future__ import annotations

import math
import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64, Float64MultiArray
from std_srvs.srv import Trigger

from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.ros.qos import COMMAND_QOS, MEASUREMENT_QOS, STATUS_QOS
from lhd_loading_ros.ros.run import number_param, run_node

from .env import LhdLoadingEnv
from .simulator import MATERIALS

# QoS (lhd_loading_ros.ros.qos, shared with the hardware bridge and the policy node): measurements
# MEASUREMENT_QOS (reliable, keep-last 5: lockstep must not lose a state, and best-effort
# subscribers still match), commands COMMAND_QOS (keep-last 1), episode status STATUS_QOS
# (transient local: a launcher that starts late still sees it). /clock: reliable keep-last 1.
CLOCK_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
MODES = ("realtime", "lockstep")
JOINTS = ("boom", "bucket", "articulation", "wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr")


def ns_time(t_ns: int):
    from builtin_interfaces.msg import Time

    return Time(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000)


class SimNode(Node):
    def __init__(self, **node_kwargs):
        super().__init__("lhd_sim", **node_kwargs)
        self.declare_parameter("config", "")
        cfg = load_config(self.get_parameter("config").value or None)
        self.declare_parameter("mode", "realtime")
        self.declare_parameter("seed", 0)
        self.declare_parameter("slope_deg", -1.0)
        # "15,20,25,30", [15.0, 20.0] or one number: any of them from the command line or YAML
        self.declare_parameter("slopes_deg", "", ParameterDescriptor(dynamic_typing=True))
        self.declare_parameter("material", "random")
        self.declare_parameter("episodes", 0)
        self.declare_parameter("auto_reset", True)
        self.declare_parameter("reset_delay", 1.0)
        self.declare_parameter("cmd_timeout", cfg["hardware"]["cmd_timeout"])
        self.declare_parameter("namespace_prefix", "/lhd")
        self.declare_parameter("frame_id", "pile")
        self.declare_parameter("base_frame_id", "base_link")
        gp = lambda n: self.get_parameter(n).value  # noqa: E731
        self.mode = gp("mode")
        if self.mode not in MODES:
            raise ValueError(f"parameter 'mode' = {self.mode!r} is invalid; expected one of {MODES}")
        self.seed = number_param(self, "seed", 0, 2**31 - 1, integer=True)
        self.episodes_max = number_param(self, "episodes", 0, 10**9, integer=True)
        slope = gp("slope_deg")
        if not isinstance(slope, (int, float)) or not math.isfinite(slope):
            raise ValueError(f"parameter 'slope_deg' = {slope!r} is invalid; expected degrees, negative for random")
        lo, hi = cfg["paper"]["episode"]["alpha_min_deg"], cfg["paper"]["episode"]["alpha_max_deg"]
        if slope >= 0 and not (lo <= slope <= hi):
            raise ValueError(f"parameter 'slope_deg' = {slope} is out of range; expected [{lo}, {hi}] degrees "
                             "or negative for a random slope")
        self.slope_deg = float(slope) if slope >= 0 else None
        self.slopes = self._slope_list(gp("slopes_deg"), lo, hi)
        material = gp("material")
        if material not in (*MATERIALS, "random"):
            raise ValueError(f"parameter 'material' = {material!r} is invalid; expected one of {(*MATERIALS, 'random')}")
        self.material = None if material == "random" else material
        self.cmd_timeout = number_param(self, "cmd_timeout", 0.01, 10.0)
        self.reset_delay = number_param(self, "reset_delay", 0.0, 60.0)
        self.auto_reset = bool(gp("auto_reset"))
        self.frame_id, self.base_frame_id = gp("frame_id"), gp("base_frame_id")
        ns = gp("namespace_prefix").rstrip("/")

        self.env = LhdLoadingEnv("rld", cfg)   # stepped with actuator commands: the variant is not used
        self.sim = self.env.sim
        self.dt = self.env.p.control_dt
        self.dt_ns = int(round(self.dt * 1e9))
        m = self.sim.model
        self._art_q = m.jnt_qposadr[m.joint("articulation").id]
        self._art_v = m.jnt_dofadr[m.joint("articulation").id]
        self._wheel_q = [m.jnt_qposadr[m.joint(w).id] for w in JOINTS[3:]]
        self._wheel_v = [m.jnt_dofadr[m.joint(w).id] for w in JOINTS[3:]]

        self.pub_clock = self.create_publisher(Clock, "/clock", CLOCK_QOS)
        self.pub_slope = self.create_publisher(Float64, f"{ns}/pile/slope", MEASUREMENT_QOS)
        self.pub_zone = self.create_publisher(Float64MultiArray, f"{ns}/pile/end_zone", MEASUREMENT_QOS)
        self.pub_front = self.create_publisher(Bool, f"{ns}/wheel_drift/front", MEASUREMENT_QOS)
        self.pub_rear = self.create_publisher(Bool, f"{ns}/wheel_drift/rear", MEASUREMENT_QOS)
        self.pub_drift = self.create_publisher(Bool, f"{ns}/wheel_drift", MEASUREMENT_QOS)
        self.pub_status = self.create_publisher(DiagnosticStatus, f"{ns}/episode", STATUS_QOS)
        self.pub_odom = self.create_publisher(Odometry, f"{ns}/odom", MEASUREMENT_QOS)
        self.pub_js = self.create_publisher(JointState, f"{ns}/joint_states", MEASUREMENT_QOS)
        self.create_subscription(Float64MultiArray, f"{ns}/cmd", self._on_cmd, COMMAND_QOS)
        self.create_service(Trigger, "~/reset", self._on_reset)

        self.t_ns = 0                    # sim time, never goes back (across episodes too)
        self.episode = -1
        self.episodes_done = 0
        self.outcome = "running"
        self.result = None
        self._cmd = np.zeros(3)
        self._cmd_time = None            # monotonic arrival time of the latest valid command
        self.rejected = 0
        self.stale_stops = 0
        self._reset_due = None
        self._last_publish = 0.0
        self._new_episode()
        if self.mode == "realtime":
            self.create_timer(self.dt, self._tick_realtime)
        else:
            # lockstep waits for a command; a subscriber that joined late (or lost a message)
            # would wait for a state: repeat the current one (same stamp) while nothing happens
            self.create_timer(0.5, self._repeat_state)
        self.get_logger().info(f"sim node up: mode {self.mode}, seed {self.seed}, slope "
                               f"{'random' if self.slope_deg is None else self.slope_deg}, material {material}")

    # ------------------------------------------------------------------ parameters
    def _slope_list(self, text, lo: float, hi: float) -> list[float]:
        if isinstance(text, (int, float)) and not isinstance(text, bool):
            text = str(text)
        elif isinstance(text, (list, tuple)):
            text = ",".join(str(v) for v in text)
        if not str(text).strip():
            return []
        try:
            vals = [float(v) for v in str(text).split(",")]
        except ValueError:
            raise ValueError(f"parameter 'slopes_deg' = {text!r} is invalid; expected comma-separated degrees "
                             "such as '15,20,25,30'") from None
        bad = [v for v in vals if not (lo <= v <= hi)]
        if bad:
            raise ValueError(f"parameter 'slopes_deg': {bad} out of range; expected degrees in [{lo}, {hi}]")
        return vals

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
        self.env.reset(seed=self.seed + self.episode, options=opts)
        self.outcome, self.result, self._reset_due = "running", None, None
        self._cmd[:] = 0.0
        self._cmd_time = None
        if self.episode > 0:
            self.t_ns += self.dt_ns      # a fresh stamp for the new episode's first state
        self.publish_state()

    def _finished_all(self) -> bool:
        return self.episodes_max > 0 and self.episodes_done >= self.episodes_max

    def _on_reset(self, request, response):
        self._new_episode()
        response.success = True
        response.message = f"episode {self.episode} started (seed {self.seed + self.episode})"
        return response

    # ------------------------------------------------------------------ commands
    def _on_cmd(self, msg: Float64MultiArray) -> None:
        data = list(msg.data)
        if len(data) != 3 or not all(math.isfinite(v) for v in data):
            self.rejected += 1
            self.get_logger().warn(f"rejected /cmd {data}: expected 3 finite values [u_wheels, u_boom, u_bucket] "
                                   "rad/s", throttle_duration_sec=1.0)
            return
        u = np.array(data)
        lo, hi = self._ranges()
        clipped = np.clip(u, lo, hi)
        if not np.array_equal(clipped, u):
            self.get_logger().warn(f"command {data} outside the actuator ranges {lo.tolist()}..{hi.tolist()} rad/s: "
                                   "clamped", throttle_duration_sec=1.0)
        self._cmd = clipped
        self._cmd_time = time.monotonic()
        if self.mode == "lockstep" and self.outcome == "running":
            self._step(self._cmd)

    def _repeat_state(self) -> None:
        if time.monotonic() - self._last_publish >= 0.5:
            self.publish_state()

    def _ranges(self):
        p = self.env.p
        return (np.array([p.wheels_min, p.boom_min, p.bucket_min]), np.array([p.wheels_max, p.boom_max, p.bucket_max]))

    def _tick_realtime(self) -> None:
        if self.outcome != "running":
            if self._reset_due is not None and time.monotonic() >= self._reset_due:
                self._new_episode()
            return
        now = time.monotonic()
        if self._cmd_time is None or now - self._cmd_time > self.cmd_timeout:
            if self._cmd_time is not None:
                self.stale_stops += 1
                self.get_logger().warn(f"no /cmd for {self.cmd_timeout} s: wheels braked, arm held",
                                       throttle_duration_sec=2.0)
            u = np.zeros(3)
        else:
            u = self._cmd
        self._step(u)

    def _step(self, u: np.ndarray) -> None:
        _, _, term, trunc, info = self.env.step_actuator(u)
        self.t_ns += self.dt_ns
        if term or trunc:
            self.outcome = info["outcome"] if term else "timeout"
            self.result = info["episode_result"]
            self.episodes_done += 1
            r = self.result
            self.get_logger().info(
                f"episode {self.episode} {self.outcome}: loaded {r.loaded:.1f} kg, SL {r.success_level}, "
                f"{r.elapsed_s:.1f} s, drift front {r.front_drift_pct:.0f} % rear {r.rear_drift_pct:.0f} %")
        self.publish_state()
        if self.outcome != "running" and self.auto_reset and not self._finished_all():
            if self.mode == "lockstep":
                self._new_episode()
            else:
                self._reset_due = time.monotonic() + self.reset_delay

    # ------------------------------------------------------------------ publishing
    def _status(self) -> DiagnosticStatus:
        st = DiagnosticStatus()
        st.name = "lhd_sim/episode"
        st.hardware_id = "mujoco"
        st.message = self.outcome + (" (all episodes done)" if self._finished_all() else "")
        st.level = DiagnosticStatus.OK if self.outcome in ("running", "success") else DiagnosticStatus.WARN
        s = self.env.state
        vals = {
            "state": self.outcome, "episode": self.episode, "seed": self.seed + self.episode,
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
        if self.result is not None:
            r = self.result
            vals.update({"success": r.success, "success_level": r.success_level, "return": f"{r.ret:.3f}",
                         "elapsed_s": f"{r.elapsed_s:.2f}", "front_drift_pct": f"{r.front_drift_pct:.2f}",
                         "rear_drift_pct": f"{r.rear_drift_pct:.2f}", "phi_final_deg": f"{math.degrees(r.phi_final):.2f}",
                         "reason": {"success": "bucket tip reached the end zone",
                                    "failure": "bucket tip entered the restricted zone",
                                    "timeout": f"{self.env.p.max_steps} control steps passed"}[self.outcome]})
        st.values = [KeyValue(key=k, value=str(v)) for k, v in vals.items()]
        return st

    def publish_state(self) -> None:
        self._last_publish = time.monotonic()
        stamp = ns_time(self.t_ns)
        d = self.sim.data
        s = self.env.state
        self.pub_clock.publish(Clock(clock=stamp))
        self.pub_slope.publish(Float64(data=float(self.sim.pile.alpha)))
        z = self.sim.zones
        self.pub_zone.publish(Float64MultiArray(data=[float(z.x_min), float(z.x_max), float(z.z_min)]))
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
        js.position = [float(s.phi_boom), float(s.phi_bucket), float(q[self._art_q])] + [float(q[i]) for i in self._wheel_q]
        js.velocity = ([float(s.dphi_boom), float(s.dphi_bucket), float(d.qvel[self._art_v])]
                       + [float(d.qvel[i]) for i in self._wheel_v])
        self.pub_js.publish(js)


def main(args=None) -> int:
    return run_node(SimNode, "lhd_sim", args)


if __name__ == "__main__":
    raise SystemExit(main())
