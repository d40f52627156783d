"""`ros2 run lhd_loading_ros supervisor_node`: the loading attempt's life cycle on the real
machine (docs/supervisor.md), a thin shell over task/attempt.py (states, preflight, end
conditions, figures) and task/attempt_record.py (the CSV).

Topics under the prefix (/lhd, or the node's namespace):
  in   joint_states, odom, wheel_drift/front, wheel_drift/rear   (sensor-data QoS: any publisher)
       pile/slope, pile/zones          (latched and volatile, as the policy node takes the slope)
       hw/status                       (diagnostic_msgs/DiagnosticStatus from the bridge)
       estop                           (std_msgs/Bool, latched; true = engaged)
       load_cell/mass                  (std_msgs/Float64 kg, optional hardware)
       attempt/mass                    (std_msgs/Float64 kg, the operator's weighed mass of the
                                        latest ended attempt: `lhd attempt mass 23.4`)
  out  episode                         (diagnostic_msgs/DiagnosticStatus "lhd_supervisor/episode",
                                        the sim node's keys; on every change and at 2 Hz)
       supervisor/markers              (visualization_msgs/MarkerArray, latched, in `frame_id`: the
                                        zones from pile/zones and the tip trajectory of the current
                                        attempt; a DELETEALL first at each new attempt)
       /diagnostics
  srv  arm, abort                      (std_srvs/Trigger)

Only state `running` lets a controller move the machine: idle, armed and every ended state
mean "stop" to every controller and to the command mux, which gates /lhd/cmd on this topic.
The supervisor itself never publishes a command. The end conditions are checked on every
joint_states / odom arrival and on a 50 Hz steady timer, so an end is published within
about 20 ms of the input that shows it.

Record: <run_dir>/attempts.csv, a row written when an attempt ends and rewritten when its mass
arrives; the bag of attempt N is expected in <run_dir>/bags/attempt_NNNN (the recorder)."""
from __future__ import annotations

import datetime
import math
import re
import time
from pathlib import Path

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from nav_msgs.msg import Odometry
from rclpy.duration import Duration
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Bool, Float64, Float64MultiArray, String
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from lhd_loading_ros.policy.actor_file import PolicyFileError, load_policy
from lhd_loading_ros.ros.diagnostics import ERROR, OK, WARN, Diagnostics
from lhd_loading_ros.ros.markers import supervisor_markers
from lhd_loading_ros.ros.params import Param, Params, steady_timer, topic_prefix
from lhd_loading_ros.ros.qos import LATCHED_QOS, MEASUREMENT_QOS, STATUS_QOS
from lhd_loading_ros.ros.run import run_node
from lhd_loading_ros.task.attempt import (ATTEMPT_TIMEOUT_RANGE_S, ENDED, LIVE, STATUS_TIMEOUT_S, HwStatus, Settings,
                                         Supervisor, placement_limits)
from lhd_loading_ros.task.attempt_record import MATERIALS, csv_path, read_rows, run_dir_problems, upsert_row
from lhd_loading_ros.task.config import config_hash, load_config
from lhd_loading_ros.task.imu_mount import zero_problem
from lhd_loading_ros.task.kinematics import ArmKinematics
from lhd_loading_ros.task.recording import next_free_attempt
from lhd_loading_ros.task.params import TaskParams
from lhd_loading_ros.task.viz import AttemptTrail, zone_boxes
from lhd_loading_ros.task.zones import Zones

# QoS (lhd_loading_ros.ros.qos). Measurements in: sensor-data QoS (best effort), which matches
# every publisher, reliable or best effort (the ArUco node's odometry is reliable); the bridge status MEASUREMENT_QOS
# as the bridge publishes it. Slope and zones: a latched subscription (LATCHED_QOS) receives
# what a latched publisher sent before this node started, a second, sensor-data one takes a
# volatile publisher (as the policy node does). E-stop: LATCHED_QOS, so a supervisor started
# after the button was pressed still sees it. The operator's mass: reliable and volatile, depth
# 10 (MASS_QOS: an entry must not be lost, and an old one must not be replayed to a later
# supervisor). Episode status out: STATUS_QOS (reliable + transient local), so a controller or
# mux that starts later gets the current state at once. Markers out: LATCHED_QOS, every array
# whole (zones and trajectory), so a viewer started later gets the current picture.
MASS_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                      durability=DurabilityPolicy.VOLATILE)
CHECK_HZ = 50.0          # end conditions on the steady clock (and on every joints / odom arrival)
RECORD_RETRY_S = 5.0     # s between tries at writing rows a write failed for (a full disk: logged each time)
STATUS_HZ = 5.0          # <prefix>/episode at least this often (the controllers' status_timeout is 1.5 s)
STALL_MARGIN_S = 0.1     # a gap between two statuses longer than status_timeout minus this: our own stall
OVERTAKEN_NS = 1_000_000_000
LABEL = re.compile(r"^[A-Za-z0-9_.-]{1,32}$")


NODE_NAME = re.compile(r"^(/[A-Za-z_][A-Za-z0-9_]*)*/?[A-Za-z_][A-Za-z0-9_]*$")


def _check_node_names(v) -> str | None:
    bad = [n for n in v if n and not NODE_NAME.match(n)]
    return (f"not node names {bad}: expected names such as 'lhd_recorder' or '/ns/lhd_recorder' "
            "([''] for none)") if bad else None


def _node_name_problem(v: str) -> str | None:
    return None if not v or re.match(r"^[A-Za-z_][A-Za-z0-9_]*$", v) else \
        "expected a node name such as end_zone_node (no namespace: this node's), or empty for none"


def _utc_stamp() -> str:
    return datetime.datetime.now(datetime.timezone.utc).strftime("%Y%m%d-%H%M%S")


def _label_problem(v: str) -> str | None:
    return None if LABEL.match(v) else "expected a label of 1-32 letters, digits, '_', '-' or '.', e.g. rld"


UNTRAINED_SLOPE_MARGIN_DEG = 1.0   # the LiDAR's error on a plane face is 0.1-0.3 deg (docs/perception.md): a pile
                                   # built at the range's edge reads a little beyond it


def untrained_slope_range_deg(cfg: dict) -> tuple[float, float, str]:
    """(lo, hi, source) of the piles a controller without a trained range may be armed on (the Tampier
    heuristic, the teacher, teleoperation: no policy_dir). Below paper.episode.alpha_min_deg the end zone
    of the lightest pile lies beyond the zones the config derives (its x_max sets the observation and
    permitted zones' reach: docs/modeling.md "Normalisers from the pile geometry"); above the gravel's
    angle of repose (task.bucket_repose_deg) no gravel pile stands. Each end widened by
    UNTRAINED_SLOPE_MARGIN_DEG for the estimate's own error (a 30 deg pile the LiDAR read as 30.1 deg
    stopped a twin run of the teacher, 2026-11-28). An actor's range is its card's, never widened."""
    ep = cfg["paper"]["episode"]
    m = UNTRAINED_SLOPE_MARGIN_DEG
    lo = float(ep["alpha_min_deg"]) - m
    hi = max(float(ep["alpha_max_deg"]), float(cfg["task"]["bucket_repose_deg"])) + m
    return lo, hi, (f"config alpha_min_deg to the gravel's angle of repose task.bucket_repose_deg, each widened by "
                    f"{m:g} deg for the estimate's error (no trained range)")


def limited_slope_range_deg(lo: float, hi: float, source: str, limits) -> tuple[float, float, str]:
    """The controller's range [lo, hi] (from `source`) within the slope_limits_deg parameter: narrowed,
    never widened; ValueError when they do not overlap."""
    lim_lo, lim_hi = (float(v) for v in limits)
    if lim_lo <= lo and lim_hi >= hi:
        return lo, hi, source
    nlo, nhi = max(lo, lim_lo), min(hi, lim_hi)
    if not nlo < nhi:
        raise ValueError(f"parameter 'slope_limits_deg' = [{lim_lo:g}, {lim_hi:g}] leaves no slope of the "
                         f"controller's range [{lo:g}, {hi:g}] deg ({source}); expected limits that overlap it")
    return nlo, nhi, f"{source}, within slope_limits_deg [{lim_lo:g}, {lim_hi:g}]"


class SupervisorNode(Node):
    def __init__(self, **node_kwargs):
        super().__init__("lhd_supervisor", **node_kwargs)
        self.params = Params(self, [
            Param("config", "", "lhd_params.yaml to use; empty: found automatically (LHD_CONFIG, then the package's)"),
            Param("run_dir", f"runs/real/{_utc_stamp()}", "run folder: attempts.csv and bags/attempt_NNNN "
                  "(give the recorder the same one)"),
            Param("controller", "rld", "label of the controller written to the record (rld, rlc, tampier, teacher, teleop); "
                  "a change applies from the next arming", check=_label_problem,
                  on_change=lambda v: setattr(self.core, "controller", v)),
            Param("policy_dir", "", "exported actor whose card gives the slope range "
                  "(trained_ranges.slope_deg); empty (the heuristic, the teacher, teleoperation): the config's "
                  "alpha_min_deg up to the larger of alpha_max_deg and task.bucket_repose_deg, each widened by 1 deg"),
            Param("slope_limits_deg", [0.0, 90.0], "deg [lo, hi]: arm only on piles inside both the controller's "
                  "range (policy_dir's card, or the untrained range) and these limits: a site's, or the range the "
                  "machine's default actor was validated on (`lhd up real` sets [10, 35] for policies/rld_drift_confirm_margin8 and "
                  "for rlc_gains: actor_file.MACHINE_SLOPE_LIMITS_DEG); the default [0, 90] limits nothing. Narrows, never widens",
                  lo=0.0, hi=90.0, length=2, check=lambda v: None if v[0] < v[1] else "expected lo < hi"),
            Param("material", "homogeneous", "pile material written to the record; a change applies from the next "
                  "arming", choices=MATERIALS, on_change=lambda v: setattr(self.core, "material", v)),
            Param("attempt_timeout", 10.0, "s from running to timeout (paper: a timeout of 10 s); a change applies "
                  "from the next arming", lo=ATTEMPT_TIMEOUT_RANGE_S[0], hi=ATTEMPT_TIMEOUT_RANGE_S[1],
                  on_change=lambda v: self.core.set_attempt_timeout(v),
                  warn_change="the paper's 10 s protects the motors from pushing at full power against the pile"),
            Param("teleop_attempt_timeout", 40.0, "s from running to timeout of a teleoperated attempt (controller "
                  "teleop): the paper's operators took 10-16 s on average, the operator on the deadman protects the "
                  "motors (docs/supervisor.md \"Teleoperated attempts\"); a change applies from the next arming",
                  lo=ATTEMPT_TIMEOUT_RANGE_S[0], hi=ATTEMPT_TIMEOUT_RANGE_S[1],
                  on_change=lambda v: self.core.set_attempt_timeout(v, teleop=True)),
            Param("arm_delay", 1.0, "s between armed and running (0: at once); the command mux holds every source "
                  "while an attempt is armed, the gamepad too", lo=0.0, hi=60.0),
            Param("status_timeout", STATUS_TIMEOUT_S, "s: the controllers' status_timeout (policy node, command mux: "
                  "they stop a running attempt whose status is older). When this node did not publish its status for "
                  "longer than that less 0.1 s (its process stalled), the running attempt is aborted with that reason, "
                  "as the controllers have stopped the machine; 0: never. Fixed at start, as the controllers' is",
                  lo=0.0, hi=60.0),
            Param("input_timeout", 0.5, "s: joints, odometry or a drift flag older than this while armed or running "
                  "ends the attempt (lost_input), and fails the preflight", lo=0.01, hi=60.0),
            Param("end_check_period", -1.0, "s: the end zone is judged at the end of each such period since "
                  "running began (-1: the task's control period, 0.1 s, as the controllers were trained; 0: on every "
                  "update); e-stop, lost input, restricted zone and timeout are checked on every update",
                  lo=-1.0, hi=10.0, check=lambda v: None if v == -1.0 or v >= 0.0 else
                  "expected -1 (the task's control period) or seconds >= 0"),
            Param("hw_status_timeout", 0.5, "s: the same for the bridge's hw/status", lo=0.01, hi=60.0),
            Param("slope_timeout", 2.0, "s: to arm, the pile slope must be younger than this (the LiDAR node sends "
                  "one per scan; a hung one leaves the previous pile's slope and zones latched); 0: no limit (a "
                  "surveyed slope published once)", lo=0.0, hi=3600.0),
            Param("zones_tolerance", 0.02, "m: during the arm delay, a zone limit re-estimated farther than this "
                  "from the one frozen at arming aborts the attempt before it starts (another pile estimate); it "
                  "matters only above the end-zone node's republish_threshold (that node publishes no smaller "
                  "change)",
                  lo=0.001, hi=1.0),
            Param("arm_fresh_fraction", 0.5, "to arm, every input must be younger than this fraction of its timeout "
                  "(an input nearly as old as its timeout would end the armed attempt one late message later)",
                  lo=0.05, hi=1.0),
            Param("max_tilt_deg", 0.0, "deg: a machine tilted beyond this (|pitch| from <prefix>/imu, an IMU on the "
                  "rear frame) ends the attempt as a failure, and the IMU becomes a required input; 0: no limit "
                  "(a fresh IMU is still used for the final pitch)", lo=0.0, hi=45.0),
            Param("imu_zero_deg", [0.0, 0.0], "[roll, pitch] deg the IMU (<prefix>/imu) reads with the machine standing "
                  "on a level floor: its mounting, taken off before any use (the ArUco node's parameter of the same name "
                  "must match; docs/real_machine.md Calibration step 9)", length=2, check=zero_problem),
            Param("max_standing_tilt_deg", 1.5, "deg: to arm, a fresh IMU must read the standing machine tilted no more "
                  "than this after imu_zero_deg (an IMU mounted 2 deg askew cost every attempt in the twin); 0: no check",
                  lo=0.0, hi=10.0),
            Param("max_heading_deg", -1.0, "deg: to arm, the machine's heading (odometry yaw in the pile frame) within "
                  "+-this of the pile's axis; -1: the parameter file's randomization.heading_max_deg (the range the "
                  "machine's actors were trained to start from; the main job's, trained straight, lose attempts within "
                  "it too); 0: no check", lo=-1.0, hi=45.0),
            Param("max_lateral_offset", -1.0, "m: to arm, the bucket tip within +-this of the pile's axis; -1: where the "
                  "lip was when a training episode began (randomization.lateral_offset_max + (d_attack_max + d_init) "
                  "sin(heading_max_deg): 0.095); 0: no check", lo=-1.0, hi=1.0),
            Param("mass_settle_s", 1.0, "s: after the machine stopped, the median of load_cell/mass over this "
                  "window is the attempt's mass", lo=0.1, hi=60.0),
            Param("namespace_prefix", "/lhd", "topic prefix in the root namespace (under a namespace, the "
                  "namespace is the prefix)"),
            Param("frame_id", "pile", "frame of the markers (the pile frame of odom and pile/zones)"),
            Param("markers_hz", 5.0, "Hz, supervisor/markers at most this often while something changed "
                  "(0: none)", lo=0.0, hi=30.0),
            Param("required_listeners", [""], "names of nodes that must subscribe to <prefix>/episode before "
                  "an attempt may be armed (a preflight item), e.g. ['lhd_recorder']: an attempt armed before the "
                  "recorder has discovered the status would have no bag; [''] for none", check=_check_node_names),
            Param("end_zone_node", "end_zone_node", "name of the end-zone node in this node's namespace: while its "
                  "/diagnostics 'zones' status is ERROR (it refuses the latest pile estimate: a toe beyond its limits, "
                  "a slope in another frame) the zones latched are an earlier estimate's, and arming is refused; "
                  "empty: not watched (surveyed zones, another zones source)", check=_node_name_problem),
            Param("min_free_mb", 100.0, "MB: to arm, the run folder's file system must have this much free space "
                  "(the record and the recorder's bag of the attempt: a few MB each); 0: no check", lo=0.0, hi=1e6),
        ])
        gp = self.params.__getitem__
        cfg = load_config(gp("config") or None)
        p = TaskParams.from_config(cfg)
        self.prefix = ns = topic_prefix(self, gp("namespace_prefix"))
        if gp("policy_dir"):
            try:
                lo, hi, source = load_policy(gp("policy_dir")).check_config(cfg).trained_slope_range_deg(cfg)
            except PolicyFileError as exc:
                raise ValueError(f"parameter 'policy_dir' = {gp('policy_dir')!r}: {exc}") from None
            source = f"{gp('policy_dir')}: {source}"
        else:
            lo, hi, source = untrained_slope_range_deg(cfg)
        lo, hi, source = limited_slope_range_deg(lo, hi, source, gp("slope_limits_deg"))
        settings = Settings(slope_range_deg=(lo, hi), slope_source=source, phi_thresh=p.phi_thresh_pitch,
                            control_dt=p.control_dt, attempt_timeout=gp("attempt_timeout"),
                            teleop_attempt_timeout=gp("teleop_attempt_timeout"),
                            arm_delay=gp("arm_delay"), input_timeout=gp("input_timeout"),
                            hw_status_timeout=gp("hw_status_timeout"), mass_settle_s=gp("mass_settle_s"), prefix=ns,
                            end_check_period=p.control_dt if gp("end_check_period") < 0 else gp("end_check_period"),
                            max_tilt_deg=gp("max_tilt_deg"), arm_fresh_fraction=gp("arm_fresh_fraction"),
                            slope_timeout=gp("slope_timeout"), zones_tolerance=gp("zones_tolerance"),
                            imu_zero=tuple(math.radians(float(v)) for v in gp("imu_zero_deg")),
                            max_standing_tilt_deg=gp("max_standing_tilt_deg"),
                            config_hash=config_hash(cfg), **placement_limits(cfg, gp("max_heading_deg"),
                                                                             gp("max_lateral_offset")))
        self.run_dir = Path(gp("run_dir")).expanduser().resolve()
        self.csv = csv_path(self.run_dir)
        try:
            self.run_dir.mkdir(parents=True, exist_ok=True)
            rows = read_rows(self.csv)
        except OSError as exc:
            raise ValueError(f"parameter 'run_dir' = {gp('run_dir')!r}: cannot use it ({exc})") from None
        except ValueError as exc:
            raise ValueError(f"parameter 'run_dir' = {gp('run_dir')!r}: its record is unreadable ({exc}); "
                             "move it away or pick another run_dir") from None
        # on from the record and the bags both: a record moved aside (as the message above asks) restarted at 1 and
        # filed attempt 1 again beside yesterday's bags/attempt_0001, which `lhd replay` then read today's mass for
        first = max(max((r.attempt for r in rows), default=0) + 1, next_free_attempt(self.run_dir))
        self.core = Supervisor(settings, ArmKinematics.from_config(cfg), gp("controller"), gp("material"), first)
        self.record_error = ""
        self.rows_written = 0
        self._unwritten: dict = {}       # attempt -> the latest row a write failed for (written again before arming)
        self._retry_at = 0.0             # monotonic time of the next try at writing them (the preflight runs at 1 Hz)
        self.min_free_bytes = self.params["min_free_mb"] * 1e6
        self._slow_source_ns: dict[str, int] = {}
        self._recorded = None            # (attempt, mass) of the latest row handed to the record
        self._status_sent = None         # monotonic time of the latest <prefix>/episode status
        self.status_timeout = self.params["status_timeout"]
        self.required_listeners = tuple(n for n in self.params["required_listeners"] if n)

        self.pub_status = self.create_publisher(DiagnosticStatus, f"{ns}/episode", STATUS_QOS)
        self.frame_id = gp("frame_id")
        self.trail = AttemptTrail()
        self._marker_zones = None          # the zones of the last array
        self.pub_markers = None
        if gp("markers_hz") > 0:
            self.pub_markers = self.create_publisher(MarkerArray, f"{ns}/supervisor/markers", LATCHED_QOS)
            steady_timer(self, 1.0 / gp("markers_hz"), self._publish_markers)
        sd = qos_profile_sensor_data
        self.create_subscription(JointState, f"{ns}/joint_states", self._on_js, sd)
        self.create_subscription(Odometry, f"{ns}/odom", self._on_odom, sd)
        self.create_subscription(Imu, f"{ns}/imu", self._on_imu, sd)
        self.create_subscription(Bool, f"{ns}/wheel_drift/front", lambda m: self._put_check("drift_front", bool(m.data)),
                                 sd)
        self.create_subscription(Bool, f"{ns}/wheel_drift/rear", lambda m: self._put_check("drift_rear", bool(m.data)),
                                 sd)
        # a volatile publisher is incompatible with the latched subscription by design (the
        # sensor-data one takes it): no warning for that
        quiet = SubscriptionEventCallbacks(incompatible_qos=lambda _: None)
        for qos, events in ((sd, None), (LATCHED_QOS, quiet)):
            self.create_subscription(Float64, f"{ns}/pile/slope", self._on_slope, qos, event_callbacks=events)
            self.create_subscription(Float64MultiArray, f"{ns}/pile/zones", self._on_zones, qos, event_callbacks=events)
        self.create_subscription(DiagnosticStatus, f"{ns}/hw/status", self._on_hw, MEASUREMENT_QOS)
        # the end-zone node's own verdict on the latest pile estimate (it keeps the last good zones latched when it
        # refuses one: without this the supervisor armed on a new pile's fresh slope with an earlier pile's zones)
        ez = self.params["end_zone_node"]
        self.end_zone_diag = (f"{self.get_namespace().rstrip('/')}/{ez}: zones") if ez else ""
        self._end_zone_error = None       # (monotonic arrival, message) of its latest status if ERROR, else None
        if ez:
            self.create_subscription(DiagnosticArray, "/diagnostics", self._on_diagnostics, 50)
        self.create_subscription(Bool, f"{ns}/estop", self._on_estop, LATCHED_QOS)
        # the command mux's selected source (latched): a running attempt whose controller's commands
        # stop reaching the machine ends (task.attempt: Supervisor._command_problem)
        self.create_subscription(String, f"{ns}/cmd_mux/active", lambda m: self._put_check("mux", str(m.data)),
                                 LATCHED_QOS)
        self.create_subscription(Float64, f"{ns}/load_cell/mass", self._on_load_cell, sd)
        self.create_subscription(Float64, f"{ns}/attempt/mass", self._on_mass, MASS_QOS)
        self.create_service(Trigger, f"{ns}/arm", self._on_arm)
        self.create_service(Trigger, f"{ns}/abort", self._on_abort)
        steady_timer(self, 1.0 / CHECK_HZ, self._check)
        steady_timer(self, 1.0 / STATUS_HZ, self._publish_status)
        self.diagnostics = Diagnostics(self, {"attempt": self._diag_attempt, "preflight": self._diag_preflight,
                                              "record": self._diag_record}, hardware_id=str(self.run_dir))
        self._publish_status()
        self.get_logger().info(f"supervisor up: record {self.csv} (next attempt {first}), controller "
                               f"{self.core.controller}, slope range [{lo:g}, {hi:g}] deg ({source}), timeout "
                               f"{self.core.timeout_for_controller:g} s, arm delay {settings.arm_delay:g} s")

    # ------------------------------------------------------------------ inputs
    def _put(self, name: str, value) -> None:
        self.core.inputs.put(name, value, time.monotonic())

    def _put_check(self, name: str, value) -> None:
        """A fast input, then the check: after a pause of this process the check that follows
        the last message taken in a pass is the one that sees the machine's state again
        (task.attempt.STALL_S)."""
        self._put(name, value)
        self._check()

    def _on_imu(self, msg: Imu) -> None:
        """REP 145: orientation_covariance[0] = -1 means the driver gives no orientation (a raw
        imu/data_raw): not an input. The orientation is taken as the machine's (x forward, z up;
        the IMU mounted level on the rear frame) in a gravity-aligned, z-up world (ENU): remap a
        driver's imu/data to <prefix>/imu. A zero or non-finite quaternion is a lost input when
        max_tilt_deg > 0."""
        if msg.orientation_covariance[0] == -1.0:
            return
        q = msg.orientation
        self._put_check("imu", (float(q.w), float(q.x), float(q.y), float(q.z)))

    def _on_js(self, msg: JointState) -> None:
        joints = {}
        for i, n in enumerate(msg.name):
            pos = float(msg.position[i]) if i < len(msg.position) else math.nan
            vel = float(msg.velocity[i]) if i < len(msg.velocity) else math.nan
            joints[n] = (pos, vel)
        self._put("joints", joints)      # a missing boom / bucket is a preflight problem and lost input
        self._check()

    def _on_odom(self, msg: Odometry) -> None:
        pp, q = msg.pose.pose.position, msg.pose.pose.orientation
        self._put("odom", ((pp.x, pp.y, pp.z), (q.w, q.x, q.y, q.z), msg.twist.twist.linear.x))
        self._check()

    def _fresh_slow(self, name: str, info) -> bool:
        """A latched value arrives through both subscriptions when its publisher is reliable: the
        second copy and a sample overtaken by a newer one are dropped (the policy node's rule)."""
        src = info["source_timestamp"]
        held = self._slow_source_ns.get(name)
        if held is not None and 0 <= held - src < OVERTAKEN_NS:
            return False
        self._slow_source_ns[name] = src
        return True

    def _on_slope(self, msg: Float64, info) -> None:
        if self._fresh_slow("slope", info):
            self._put("slope", float(msg.data))

    def _on_zones(self, msg: Float64MultiArray, info) -> None:
        if not self._fresh_slow("zones", info):
            return
        try:
            zones = Zones.from_list(msg.data)
        except (ValueError, TypeError) as exc:
            self.core.inputs.zones_error = str(exc)
            self.get_logger().warn(f"{self.prefix}/pile/zones refused: {exc}", throttle_duration_sec=2.0)
            return
        self._put("zones", zones)

    def _on_hw(self, msg: DiagnosticStatus) -> None:
        kv = {k.key: k.value for k in msg.values}
        estop = kv.get("estop", "False").strip().lower() == "true"
        level = msg.level if isinstance(msg.level, int) else int.from_bytes(msg.level, "little")
        stale = kv.get("command_stale", "False").strip().lower() == "true"
        self._put("hw", HwStatus(level=level, estop=estop, message=msg.message, command_stale=stale))
        self._check()

    def _on_estop(self, msg: Bool) -> None:
        if bool(msg.data) != self.core.inputs.estop:
            self.get_logger().warn(f"{self.prefix}/estop {'ENGAGED' if msg.data else 'released'}")
        self.core.inputs.estop = bool(msg.data)
        self._check()

    def _on_load_cell(self, msg: Float64) -> None:
        why = self.core.load_cell(float(msg.data), time.monotonic())
        if why:
            self.get_logger().warn(why, throttle_duration_sec=2.0)

    def _on_mass(self, msg: Float64) -> None:
        try:
            row = self.core.set_mass(msg.data, "operator")
        except ValueError as exc:
            self.get_logger().warn(f"{self.prefix}/attempt/mass {msg.data!r} refused: {exc}")
            return
        self.get_logger().info(f"attempt {row.attempt}: weighed {row.mass_kg:.2f} kg, SL {row.success_level}, "
                               f"success {row.success}")
        self._write(row)              # record first: the status then confirms a recorded mass
        self._publish_status()

    # ------------------------------------------------------------------ services
    def _listener_problems(self) -> list[str]:
        """A preflight item per required listener (parameter required_listeners) that does not
        subscribe to <prefix>/episode: it would miss the attempt (a recorder: no bag)."""
        if not self.required_listeners:
            return []
        topic = f"{self.prefix}/episode"
        subs = self.get_subscriptions_info_by_topic(topic)
        present = {i.node_name for i in subs} | {f"{i.node_namespace.rstrip('/')}/{i.node_name}" for i in subs}
        # no "; " inside: the arm answer and `lhd up real`'s checklist split the problems on it
        return [f"node {n} does not listen to {topic} yet (required_listeners): it would miss the attempt "
                "(is it running?)" for n in self.required_listeners if n not in present]

    def _on_diagnostics(self, msg) -> None:
        for st in msg.status:
            if st.name == self.end_zone_diag:
                self._end_zone_error = (time.monotonic(), st.message) if st.level == DiagnosticStatus.ERROR else None

    def _end_zone_problems(self) -> list[str]:
        """A preflight item while the end-zone node's latest status says it refuses the latest pile estimate (a
        review, 2026-11-29: the previous pile's zones stayed latched and an attempt was armed with them). Kept until
        a status of that node says otherwise: a node that died or hung in that state keeps arming refused (fail
        closed; restart it, or set end_zone_node to '' for zones from elsewhere)."""
        e = self._end_zone_error
        if e is None:
            return []
        return [f"the end-zone node refuses the latest pile estimate ({e[1]}): the zones in use are an earlier "
                "estimate's; fix the scan (the toe, the frame) or the end-zone node's limits"]

    def _record_problems(self) -> list[str]:
        """A preflight item when the run folder cannot take this attempt's record and bag: not writable, less than
        min_free_mb free, or rows of earlier attempts still unwritten (a review, 2026-11-29: on a full disk the
        attempts ran, the console printed them, and attempts.csv and the bags were never written)."""
        out = []
        if self._unwritten and self.core.state not in LIVE and time.monotonic() >= self._retry_at:
            self._retry_at = time.monotonic() + RECORD_RETRY_S
            for row in list(self._unwritten.values()):
                self._write(row)                    # written once there is room again: nothing is lost
        if self._unwritten:
            out.append(f"attempt(s) {', '.join(str(n) for n in sorted(self._unwritten))} not yet written to the "
                       f"record ({self.record_error}): free space or fix {self.run_dir}, they are written "
                       "before the next arming")
        return out + run_dir_problems(self.run_dir, self.csv, self.min_free_bytes)

    def _preflight_extra(self) -> list[str]:
        return self._end_zone_problems() + self._record_problems() + self._listener_problems()

    def _on_arm(self, request, response):
        self._retry_at = 0.0                        # the rows not yet written: tried again now
        ok, message = self.core.arm(time.monotonic(), datetime.datetime.now(datetime.timezone.utc)
                                    .strftime("%Y-%m-%dT%H:%M:%SZ"), self._preflight_extra())
        response.success, response.message = ok, message
        if ok:
            # the attempt in the record first, then its status (a review: a status published before a failed write
            # let the mux see a live attempt for an instant): if this process dies before the end, the row says so
            # (aborted, INTERRUPTED_REASON) instead of the attempt and its bag going unrecorded
            if not self._write(self.core.attempt.provisional_row()):
                # the check above passed and the write failed all the same: not started, nothing published yet
                self.core.abort(time.monotonic(), f"not started: {self.record_error}")
                self._after_end()
                response.success = False
                response.message = f"not armed: {self.record_error}"
                return response
            self.get_logger().info(message)
            self._publish_status()
        else:
            self.get_logger().warn(message)
        return response

    def _on_abort(self, request, response):
        ok, message = self.core.abort(time.monotonic())
        response.success, response.message = ok, message
        if ok:
            self._after_end()
        return response

    # ------------------------------------------------------------------ the loop
    def _own_stall(self, now: float) -> bool:
        """This node did not run, and so sent no status, for longer than the controllers wait for one
        (status_timeout, less STALL_MARGIN_S): they have ended the running attempt and stopped the
        machine. The attempt is aborted with that reason (a set-up fault: repeated, not counted),
        instead of running on to a timeout with nobody commanding."""
        if (self.core.state != "running" or self._status_sent is None or self.status_timeout <= 0.0
                or now - self._status_sent <= self.status_timeout - STALL_MARGIN_S):
            return False
        gap = now - self._status_sent
        self.core.abort(now, f"the supervisor did not run for {gap:.1f} s (its process stalled): its status stopped "
                             f"for longer than the controllers' status_timeout ({self.status_timeout:g} s), so they "
                             "stopped the machine; repeat the attempt")
        self.get_logger().error(f"attempt {self.core.attempt.number} aborted: this node did not run for {gap:.1f} s")
        self._after_end()
        return True

    def _check(self) -> None:
        c = self.core
        if self._own_stall(time.monotonic()):
            return
        changed = c.update(time.monotonic())
        tip = c.tip
        self.trail.update(c.attempt.number if c.attempt is not None else None, c.state in LIVE,
                          (tip.x_shovel, tip.y_shovel, tip.z_shovel) if tip is not None else None)
        if changed:
            if c.state in ENDED:
                self._after_end()
            else:
                self.get_logger().info(f"attempt {c.attempt.number} {c.state}")
                self._publish_status()
        elif c.state in ENDED and (c.attempt.number, c.attempt.mass) != self._recorded:
            row = c.attempt.row()         # the load cell gave the mass
            self.get_logger().info(f"attempt {row.attempt}: load cell {row.mass_kg:.2f} kg, SL "
                                   f"{row.success_level}, success {row.success}")
            self._write(row)
            self._publish_status()

    def _publish_markers(self) -> None:
        zones = self.core.inputs.values.get("zones")
        if not self.trail.dirty and zones is self._marker_zones:
            return
        self._marker_zones = zones
        points, clear = self.trail.take()
        boxes = zone_boxes(zones) if zones is not None else []
        self.pub_markers.publish(supervisor_markers(self.get_clock().now().to_msg(), self.frame_id, boxes, points,
                                                    clear))

    def _after_end(self) -> None:
        """The end: status first (controllers and the mux stop on it), then the record."""
        a = self.core.attempt
        self._publish_status()
        row = a.row()
        self.get_logger().info(f"attempt {a.number} {a.outcome}: {a.reason}; {row.elapsed_s:.2f} s, drift front "
                               f"{row.front_drift_pct:.0f} % rear {row.rear_drift_pct:.0f} %, final pitch "
                               f"{row.phi_final_deg:.1f} deg")
        self._write(row)

    def _write(self, row) -> bool:
        # what _check compares: the attempt's own mass, not the row's (rounded to the record's 10 g: a
        # load cell's 22.004 kg is a row of 22.00, and comparing the two rewrote the row and logged it at
        # 50 Hz until the next arming). A failed write is reported, not retried at 50 Hz
        a = self.core.attempt
        self._recorded = (a.number, a.mass) if a is not None and a.number == row.attempt else (row.attempt, row.mass_kg)
        try:
            upsert_row(self.csv, row)
            self.rows_written += 1
            self._unwritten.pop(row.attempt, None)
            if not self._unwritten:
                self.record_error = ""
            return True
        except (OSError, ValueError) as exc:
            self.record_error = f"cannot write {self.csv}: {exc}"
            self._unwritten[row.attempt] = row
            self.get_logger().error(self.record_error + f" (attempt {row.attempt} kept in memory, written again "
                                    "before the next arming)")
            return False

    def _publish_status(self) -> None:
        if self._own_stall(time.monotonic()):
            return                                  # (it published the aborted status)
        self._status_sent = time.monotonic()
        now_ns = self.get_clock().now().nanoseconds
        values = self.core.status_values(time.monotonic())
        values["stamp_ns"] = str(now_ns)
        values["run_dir"] = str(self.run_dir)
        st = DiagnosticStatus()
        st.name = "lhd_supervisor/episode"
        st.hardware_id = str(self.run_dir)
        st.message = values["state"]
        st.level = DiagnosticStatus.OK if values["state"] in ("idle", "armed", "running", "success") \
            else DiagnosticStatus.WARN
        st.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        self.pub_status.publish(st)

    def stop(self) -> None:
        """On the way out: an attempt still live ends as aborted (published, so that every
        controller stops, and recorded)."""
        if self.core.state in LIVE and self.context.ok():
            self.core.abort(time.monotonic(), "supervisor stopped during the attempt")
            self._after_end()
            # a reliable writer destroyed right after a write may drop it: wait for the acks
            self.pub_status.wait_for_all_acked(Duration(seconds=0.5))

    # ------------------------------------------------------------------ diagnostics
    def _diag_attempt(self):
        c = self.core
        values = c.status_values(time.monotonic())
        level = WARN if c.state in ("estop", "lost_input", "failure") else OK
        return level, f"{c.state}: {values['reason']}", values

    def _diag_preflight(self):
        problems = self.core.preflight(time.monotonic(), self._preflight_extra())
        if self.core.state in LIVE:
            return OK, f"attempt {self.core.attempt.number} {self.core.state}", {}
        if problems:
            # each problem also as its own value (problem_1..n): a reader lists them without
            # splitting the message, whose sentences may hold "; " themselves
            return WARN, "not ready to arm: " + "; ".join(problems), {
                "problems": len(problems), **{f"problem_{k}": p for k, p in enumerate(problems, 1)}}
        return OK, "ready to arm", {}

    def _diag_record(self):
        values = {"csv": str(self.csv), "writes": self.rows_written, "unwritten": len(self._unwritten)}
        if self.record_error:
            return ERROR, self.record_error + (f" (attempt(s) {', '.join(str(n) for n in sorted(self._unwritten))} "
                                               "not written yet)" if self._unwritten else ""), values
        return OK, f"record {self.csv}", values


def main(args=None) -> int:
    return run_node(SupervisorNode, "lhd_supervisor", args, before_destroy=lambda n: n.stop())


if __name__ == "__main__":
    raise SystemExit(main())
