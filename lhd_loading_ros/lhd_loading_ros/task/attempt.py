"""The life cycle of a loading attempt on the real machine, without ROS (the supervisor node is
a thin shell over this).

    idle --arm (preflight passes)--> armed --arm_delay--> running --> ended
    ended = success | failure | timeout | estop | lost_input | aborted
    ended --arm (preflight passes)--> armed ...

Only `running` lets a controller move the machine; every other state means "stop" to every
controller (and the command mux). `idle` is the state before the first attempt; an ended
state stays until the next arming. While armed or running:
  estop       /lhd/estop engaged, or the bridge reports the device's e-stop;
  lost_input  joints, odometry, a drift flag or the bridge status older than its timeout (a
              pause of the caller itself not counted: STALL_S),
              a non-finite value, or the bridge reporting ERROR / STALE;
and while running, checked in this order after those two:
  success     the bucket tip in the end zone (task.zones.classify), judged at the end of each
              control period since running began (`end_check_period`, the task's 0.1 s: the
              POMDP's termination instants; 0: on every update);
  failure     the tip in the restricted zone (on every update: it protects the machine), or, with
              `max_tilt_deg` > 0, the machine tilted beyond it (an IMU on the rear frame, /lhd/imu:
              the rear lifting in a breakout; checked before the end zone, and in the preflight);
  timeout     attempt_timeout (10 s, the paper's) since running began;
  aborted     the operator's /lhd/abort (any time while armed or running).
The tip comes from odometry + joint states through the kinematics the policy node uses
(task.kinematics.state_from_measurements); with a fresh IMU orientation (optional; required when
max_tilt_deg > 0) the bucket's pitch is computed with the odometry's heading and the IMU's roll
and pitch (task.kinematics.with_tilt), so the final pitch includes the machine's own pitch, which
a levelled pose leaves out; the tip's position is the odometry's (the ArUco node with the IMU
publishes the tilted pose, base_link raised, so the tip is the machine's; without it, the levelled
pose's, as the controllers then see it); the zones and the slope are those of the arming
(the pile of this attempt), so a pile estimate republished mid-attempt cannot move the goal.

The figures: elapsed time from running to the end; front/rear drift % over the drift flags
sampled once per control period (10 Hz) while running, task.metrics.drift_pct, the
simulator's definition; the final pitch phi_shovel at the end (the last tip computed); the
success level once weighed (task.metrics.success_level; attempt_record.judge).

Times are monotonic seconds given by the caller (a fake clock in the tests)."""
from __future__ import annotations

import math
import statistics
from collections import deque
from dataclasses import dataclass, field, fields, replace

from lhd_loading_ros.task.attempt_record import (INTERRUPTED_REASON, AttemptRow, bag_name, check_mass, judge,
                                                 never_ran_refusal)
from lhd_loading_ros.task.imu_mount import level_orientation, zero_problem
from lhd_loading_ros.task.kinematics import ArmKinematics, nose_down_pitch, quat_to_mat, state_from_measurements, with_tilt
from lhd_loading_ros.task.metrics import drift_pct
from lhd_loading_ros.task.state import LhdState
from lhd_loading_ros.task.zones import Zones, classify

# s after running began by which an autonomous controller's commands must have reached the mux (its
# `auto` source selected): the policy node publishes at 10 Hz and the mux forwards at once, so ten
# commands fit; none in that time is a controller that is not running or publishes elsewhere
FIRST_COMMAND_S = 1.0
STATES = ("idle", "armed", "running", "success", "failure", "timeout", "estop", "lost_input", "aborted")
ENDED = frozenset(STATES[3:])
LIVE = frozenset(("armed", "running"))
# diagnostic_msgs/DiagnosticStatus levels, as numbers (this module is ROS-free)
OK, WARN, ERROR, STALE = 0, 1, 2, 3
LEVEL_NAMES = {OK: "OK", WARN: "WARN", ERROR: "ERROR", STALE: "STALE"}
STOP_SPEED = 0.05          # rad/s: every joint slower than this = the machine stopped (load-cell window)
STOP_WINDOW_S = 0.5        # s: ... on the mean of its joint-state velocities over this window, not on one message.
                           # The arm's rates are differences of sampled angles (the Due's, over 0.1 s): their noise
                           # (0.025 rad/s sd at 0.1 deg on the angles, 0.25 over one 10 ms frame) crosses 0.05 in
                           # some message of every second, and a still machine was never weighed (twin, 2026-11-29);
                           # the mean of differences over 0.5 s is the angle's change over it, sqrt(2) sd / 0.5 s
STOP_SPREAD = 0.045        # rad: ... and its positions over the window within this of each other (STOP_SPEED x
                           # STOP_WINDOW_S = 0.025 of travel, and 0.02 for the angles' noise: 25 samples of 0.1 deg
                           # span about 0.007), so that a joint swinging back and forth, whose mean speed is
                           # near 0, is not stopped: a bounce of more than +-1.3 deg keeps the machine "moving"
LOAD_CELL_MIN_SAMPLES = 3
LOAD_CELL_RANGE = (-5.0, 200.0)   # kg: a reading outside is a broken amplifier, not a load (tare noise is < 0)
RANGE_TOL_DEG = 1e-6       # a slope published in rad at exactly a range end is inside (policy core's rule)
# The caller updates every 20 ms (the node's 50 Hz check) and after taking every joints / odometry /
# drift / IMU / bridge status / e-stop message. A gap longer than STALL_S since the caller last ran
# (its previous update or the last input it took) means its process did not run (CPU starvation, a
# garbage-collection or swap pause): the inputs that arrived meanwhile wait in its queues, and the
# executor runs the timer before it takes them (rclpy: timers, then subscriptions, in one pass). An
# input's age therefore leaves out the largest such pause (beyond STALL_S) that began after the
# input was taken: input_timeout counts the caller's running time. While an input taken before a
# pause is not lost and not yet renewed ("held": newer messages may be queued), nothing that needs
# the machine's present state is decided: no start after the arm delay, no success; the safety ends
# stay (docs/supervisor.md "A stalled supervisor").
STALL_S = 0.1
ATTEMPT_TIMEOUT_RANGE_S = (0.1, 600.0)   # the supervisor's attempt_timeout (the paper: 10 s)
# s: the controllers (policy node, command mux; their `status_timeout`) end a running attempt whose
# <prefix>/episode status is older than this: the supervisor crashed or hung. The supervisor, which
# publishes its status at 5 Hz, aborts an attempt over which it did not run for nearly this long
# (supervisor_node: its own stall), so that its record agrees with what the controllers did.
STATUS_TIMEOUT_S = 1.5
STALL_MEMORY_S = 30.0      # s: a pause is forgotten this long after it ended (any input older is long lost)
ZONE_LIMITS = tuple(f.name for f in fields(Zones))
ZONES_CHANGED_M = 0.02     # m: a zone limit republished this far from arming's = another pile estimate
                           # (Settings.zones_tolerance's default; the end-zone node republishes on 2 cm)
REASONS = {
    "success": "bucket tip reached the end zone",
    "failure": "bucket tip entered the restricted zone",
    "aborted": "aborted by the operator",
}


@dataclass(frozen=True)
class HwStatus:
    """What the supervisor needs of the bridge's <prefix>/hw/status."""
    level: int
    estop: bool
    message: str
    command_stale: bool = False       # the bridge's watchdog: no valid command for its cmd_timeout


@dataclass(frozen=True)
class Settings:
    slope_range_deg: tuple[float, float]
    slope_source: str                 # where the range comes from (policy card / config), for messages
    phi_thresh: float                 # rad, the success test's pitch threshold
    control_dt: float = 0.1           # s, drift sampling period (the 10 Hz control period)
    attempt_timeout: float = 10.0     # s (paper: "a timeout of 10 seconds is added to the loading attempts")
    # s, the same for a teleoperated attempt (controller "teleop"): the paper's Teleop attempts took 10.4-16.4 s on
    # average (+-7 s) and "sometimes more than three times longer" than the controllers', so its operators were not
    # held to the 10 s that protects the motors from a controller pushing blindly; the operator on the deadman is
    # that protection. 40 s: past the paper's slowest mean plus three sd (16.4 + 3 x 7 = 37 s); a bound, not a limit
    # on the operator (docs/supervisor.md "Teleoperated attempts")
    teleop_attempt_timeout: float = 40.0
    arm_delay: float = 1.0            # s between armed and running
    input_timeout: float = 0.5        # s, joints / odometry / drift flags
    hw_status_timeout: float = 0.5    # s, the bridge's status
    mass_settle_s: float = 1.0        # s, load-cell window after the machine stopped
    prefix: str = "/lhd"              # topic prefix, for the messages
    # s: the end zone is judged at the end of each such period since running began, as the task
    # (the POMDP the controllers were trained on) judges it at the end of each control step; the
    # safety ends (e-stop, lost input, restricted zone, timeout) are checked on every update.
    # 0: the end zone on every update too (docs/supervisor.md: why the task's grid is the default)
    end_check_period: float = 0.1
    # deg: while running, the machine's tilt (|pitch| from the IMU) beyond this ends the attempt
    # as a failure; 0: no limit, and the IMU is optional (used for the pitch when it is fresh)
    max_tilt_deg: float = 0.0
    # to ARM, each input must be younger than this fraction of its timeout: an input 0.49 s old
    # passes a 0.5 s timeout but ends the armed attempt (lost_input) one late message later.
    # Half leaves room for several messages of every input (10-30 Hz) and still refuses a stalling
    # one; the running checks keep the whole timeout
    arm_fresh_fraction: float = 0.5
    # s: to arm, the pile slope must be younger than this (the LiDAR node sends one per scan; a hung
    # LiDAR node would leave the previous pile's slope and zones latched); 0: no limit (a surveyed,
    # latched slope). The supervisor node's default is 2 s
    slope_timeout: float = 0.0
    # m: during the arm delay, a zone limit re-estimated farther than this from the one frozen at
    # arming aborts the attempt before it starts (another pile estimate: a new pile, the machine
    # moved). The end-zone node republishes only a change beyond its republish_threshold (2 cm), so
    # this matters only above that threshold. On a rough face the LiDAR's median can move the end
    # zone by a few cm between scans (docs/perception.md "Rough faces"): there the end-zone node's
    # republish_threshold goes up to 0.05 (this tolerance may stay: every change then published is
    # larger than 5 cm)
    zones_tolerance: float = ZONES_CHANGED_M
    config_hash: str = ""             # the parameter file's (task.config.config_hash), written to every row
    # to ARM, the machine placed as the actors were trained to start: its heading (the odometry's yaw in the pile
    # frame) within +-max_heading_deg of the pile's axis, and the bucket tip within +-max_lateral_offset m of it
    # (placement_limits: from the randomization ranges, 4 deg and 0.095 m). Beyond, the machine's actors fail: at 10
    # deg 74-88 % of the attempts (two thirds of rld_machine's leave the permitted zone sideways), 6 deg with 0.10 m
    # about half (docs/supervisor.md "Placement"). 0: no check (the paper's protocol: placed straight by the operator)
    max_heading_deg: float = 0.0
    max_lateral_offset: float = 0.0
    # rad, (roll, pitch) the IMU reads with the machine standing on a level floor: its mounting, taken off its
    # orientation before any use (task/imu_mount.py; docs/real_machine.md Calibration step 9)
    imu_zero: tuple = (0.0, 0.0)
    # deg: to ARM, a fresh IMU must read the machine (standing on its wheels in the attack pose) tilted no more than
    # this, after imu_zero: an IMU mounted 2 deg askew cost rld_machine every attempt in the twin. 0: no check
    max_standing_tilt_deg: float = 0.0

    def __post_init__(self):
        lo, hi = self.slope_range_deg
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise ValueError(f"slope range {self.slope_range_deg!r}: expected [lo, hi] degrees, lo < hi")
        for name in ("control_dt", "attempt_timeout", "teleop_attempt_timeout", "input_timeout", "hw_status_timeout",
                     "mass_settle_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} = {v!r}: expected a positive number of seconds")
        if not (math.isfinite(self.zones_tolerance) and 0.0 < self.zones_tolerance <= 1.0):
            raise ValueError(f"zones_tolerance = {self.zones_tolerance!r}: expected metres in (0, 1]")
        if not (math.isfinite(self.arm_delay) and self.arm_delay >= 0):
            raise ValueError(f"arm_delay = {self.arm_delay!r}: expected seconds >= 0")
        if not (math.isfinite(self.max_tilt_deg) and 0.0 <= self.max_tilt_deg <= 45.0):
            raise ValueError(f"max_tilt_deg = {self.max_tilt_deg!r}: expected degrees in [0, 45] (0: no limit)")
        if not (math.isfinite(self.arm_fresh_fraction) and 0.0 < self.arm_fresh_fraction <= 1.0):
            raise ValueError(f"arm_fresh_fraction = {self.arm_fresh_fraction!r}: expected a fraction of the input "
                             "timeouts in (0, 1]")
        if not (math.isfinite(self.max_heading_deg) and 0.0 <= self.max_heading_deg <= 45.0):
            raise ValueError(f"max_heading_deg = {self.max_heading_deg!r}: expected degrees in [0, 45] (0: no check)")
        if not (math.isfinite(self.max_lateral_offset) and 0.0 <= self.max_lateral_offset <= 1.0):
            raise ValueError(f"max_lateral_offset = {self.max_lateral_offset!r}: expected metres in [0, 1] (0: no check)")
        why = zero_problem([math.degrees(v) for v in self.imu_zero])
        if why:
            raise ValueError(f"imu_zero = {self.imu_zero!r} rad: {why}")
        if not (math.isfinite(self.max_standing_tilt_deg) and 0.0 <= self.max_standing_tilt_deg <= 10.0):
            raise ValueError(f"max_standing_tilt_deg = {self.max_standing_tilt_deg!r}: expected degrees in [0, 10] "
                             "(0: no check)")
        if not (math.isfinite(self.slope_timeout) and self.slope_timeout >= 0):
            raise ValueError(f"slope_timeout = {self.slope_timeout!r}: expected seconds >= 0 (0: no limit)")
        if not (math.isfinite(self.end_check_period) and self.end_check_period >= 0):
            raise ValueError(f"end_check_period = {self.end_check_period!r}: expected seconds >= 0 (0: every update)")


def placement_limits(cfg: dict, max_heading_deg: float, max_lateral_offset: float) -> dict:
    """Settings' max_heading_deg / max_lateral_offset from the supervisor's parameters: -1 takes the range the
    parameter file's actors were trained to start from, any other value >= 0 stands (0: no check). Heading: its
    randomization.heading_max_deg. Lateral: where the lip was when a training episode began, placed within
    randomization.lateral_offset_max of the axis and driven in over at most d_attack_max + d_init at up to that
    heading: lateral_offset_max + (d_attack_max + d_init) sin(heading_max) (0.06 + 0.5 sin 4 deg = 0.095 m); the
    supervisor arms a machine standing with its tip in the pile, after that drive."""
    for name, v in (("max_heading_deg", max_heading_deg), ("max_lateral_offset", max_lateral_offset)):
        if not (v == -1.0 or (math.isfinite(v) and v >= 0.0)):
            raise ValueError(f"{name} = {v!r}: expected -1 (the parameter file's training range), 0 (no check) or a limit")
    r = cfg.get("randomization", {})
    try:
        h = float(r["heading_max_deg"])
        lateral = float(r["lateral_offset_max"]) + (float(r["d_attack_max"]) + float(cfg["paper"]["episode"]["d_init"])) \
            * math.sin(math.radians(h))
    except KeyError as exc:
        raise ValueError(f"max_heading_deg / max_lateral_offset -1 take the parameter file's randomization ranges, "
                         f"and it has no {exc.args[0]!r}: set both explicitly") from None
    return {"max_heading_deg": h if max_heading_deg == -1.0 else float(max_heading_deg),
            "max_lateral_offset": lateral if max_lateral_offset == -1.0 else float(max_lateral_offset)}


@dataclass
class Inputs:
    """Latest value and arrival time (monotonic s) of each input.
    joints: {name: (position, velocity)}; odom: ((x, y, z), (w, x, y, z), v_x); imu: (w, x, y, z);
    drift_front / drift_rear: bool; slope: rad; zones: Zones; hw: HwStatus."""
    values: dict = field(default_factory=dict)
    arrival: dict = field(default_factory=dict)
    zones_error: str = ""             # the latest zones message was invalid: why
    estop: bool = False               # <prefix>/estop (latched); never received = released

    joint_history: deque = field(default_factory=deque)   # (arrival, {joint: (position, velocity)}) over STOP_WINDOW_S
    pauses: deque = field(default_factory=deque)   # (start, excess over STALL_S) of the caller's pauses
    last_active: float | None = None  # the caller's latest input taken or update (it was running)

    def active(self, now: float) -> None:
        """The caller runs at `now` (takes an input, or checks): a gap over STALL_S since it last
        did is a pause. Called first by every put and update, so whichever runs first after a
        pause (the timer's check, or a callback taking its message) notes it."""
        if self.last_active is not None and now - self.last_active > STALL_S:
            self.note_pause(self.last_active, now - self.last_active - STALL_S, now)
        if self.last_active is None or now > self.last_active:
            self.last_active = now

    def put(self, name: str, value, now: float) -> None:
        self.active(now)
        self.values[name] = value
        self.arrival[name] = now
        if name == "zones":
            self.zones_error = ""
        elif name == "joints":
            self.joint_history.append((now, dict(value)))
            while self.joint_history and self.joint_history[0][0] < now - STOP_WINDOW_S:
                self.joint_history.popleft()

    def note_pause(self, start: float, excess: float, now: float) -> None:
        """The caller did not run from `start` for STALL_S + excess (seconds)."""
        self.pauses.append((start, excess))
        while self.pauses and self.pauses[0][0] + STALL_S + self.pauses[0][1] < now - STALL_MEMORY_S:
            self.pauses.popleft()          # ended STALL_MEMORY_S ago (the pause just noted never)

    def paused_since(self, name: str) -> float:
        """The largest pause excess that began after the input was taken (0 if none)."""
        t = self.arrival.get(name, math.inf)
        return max((e for start, e in self.pauses if start >= t), default=0.0)

    def age(self, name: str, now: float, discount: bool = True) -> float:
        """Seconds since the input was taken; discount: less the caller's pause since then."""
        if name not in self.arrival:
            return math.inf
        return now - self.arrival[name] - (self.paused_since(name) if discount else 0.0)


def _finite(*xs) -> bool:
    return all(isinstance(x, (int, float)) and math.isfinite(x) for x in xs)


@dataclass
class Attempt:
    number: int
    started_utc: str
    controller: str
    material: str
    slope_rad: float
    zones: Zones
    armed_at: float
    timeout: float = 10.0                 # attempt_timeout at arming
    running_at: float | None = None
    ended_at: float | None = None
    outcome: str = ""
    reason: str = ""
    front: list = field(default_factory=list)
    rear: list = field(default_factory=list)
    end_checks: int = 0                   # end_check_period ends judged so far
    auto_seen: bool = False               # the command mux selected the autonomous controller while running
    config_hash: str = ""                 # the supervisor's parameter file (Settings.config_hash)
    phi_thresh: float = math.nan          # rad, the success test's threshold it is judged on (Settings.phi_thresh)
    last_state: LhdState | None = None    # the latest tip while armed / running
    mass: float | None = None
    mass_source: str = ""
    success_level: int | None = None
    success: bool | None = None

    @property
    def elapsed_s(self) -> float:
        if self.running_at is None:
            return 0.0
        return (self.ended_at if self.ended_at is not None else math.inf) - self.running_at

    @property
    def phi_final(self) -> float:
        return self.last_state.phi_shovel if self.last_state is not None else math.nan

    def provisional_row(self) -> AttemptRow:
        """The row written at arming, replaced when the attempt ends: if the supervisor dies first
        (killed, the computer loses power) the record still has the attempt, as aborted and why."""
        return replace(self.row(), outcome="aborted", reason=INTERRUPTED_REASON, elapsed_s=0.0, mass_kg=None,
                       success_level=None, success=False, phi_final_deg=math.nan)

    def row(self) -> AttemptRow:
        return AttemptRow(attempt=self.number, started_utc=self.started_utc, controller=self.controller,
                          slope_deg=math.degrees(self.slope_rad), material=self.material, outcome=self.outcome,
                          reason=self.reason, mass_kg=self.mass, elapsed_s=self.elapsed_s,
                          front_drift_pct=drift_pct(self.front), rear_drift_pct=drift_pct(self.rear),
                          phi_final_deg=math.degrees(self.phi_final), success_level=self.success_level,
                          success=self.success, bag=bag_name(self.number), config_hash=self.config_hash,
                          phi_thresh_deg=math.degrees(self.phi_thresh))


class Supervisor:
    """One machine's attempts. The caller feeds `inputs`, calls `update(now)` after taking every
    joints / odometry / drift / IMU / bridge status / e-stop message and on a fast timer (50 Hz),
    and `arm`, `abort`, `set_mass`, `load_cell`. A gap between those calls longer than STALL_S
    is taken for a pause of the caller (the rule above STALL_S)."""

    def __init__(self, settings: Settings, kin: ArmKinematics, controller: str, material: str,
                 first_attempt: int = 1):
        self.s = settings
        self.kin = kin
        self.controller = controller
        self.material = material
        self.inputs = Inputs()
        self.state = "idle"
        self.next_number = first_attempt
        self.attempt: Attempt | None = None
        self.tip: LhdState | None = None         # the latest tip computed from fresh, finite inputs
        self._cell: deque = deque()              # (time, kg) load-cell samples, the last few seconds
        self._stopped_since: float | None = None

    def set_attempt_timeout(self, seconds: float, teleop: bool = False) -> None:
        """A new attempt_timeout (teleop: teleop_attempt_timeout), from the next arming on (a live attempt keeps its
        own)."""
        self.s = replace(self.s, **{"teleop_attempt_timeout" if teleop else "attempt_timeout": seconds})

    @property
    def timeout_for_controller(self) -> float:
        """s: the timeout an attempt armed now gets (teleop_attempt_timeout for a teleoperated one)."""
        return self.s.teleop_attempt_timeout if self.controller == "teleop" else self.s.attempt_timeout

    # ------------------------------------------------------------------ preflight
    def slope_problem(self, slope: float) -> str:
        if not _finite(slope):
            return f"pile slope is not a finite number ({slope!r} rad) on {self.s.prefix}/pile/slope"
        lo, hi = self.s.slope_range_deg
        deg = math.degrees(slope)
        if lo - RANGE_TOL_DEG <= deg <= hi + RANGE_TOL_DEG:
            return ""
        shown = f"{deg:.1f}"
        if float(shown) in (lo, hi) or lo <= float(shown) <= hi:     # rounding would put it inside: say more
            shown = f"{deg:.3f}"
        return (f"pile slope {shown} deg is outside the controller's range [{lo:g}, {hi:g}] deg "
                f"({self.s.slope_source}): reshape the pile or pick a controller trained for it")

    def _timed_inputs(self) -> tuple:
        """(name, what, source, timeout) of the inputs an attempt needs all the time."""
        s, p = self.s, self.s.prefix
        ages = (("joints", "joint states", f"{p}/joint_states, the bridge", s.input_timeout),
                ("odom", "odometry v_x", f"{p}/odom, the ArUco node", s.input_timeout),
                ("drift_front", "front drift flag", f"{p}/wheel_drift/front, the bridge", s.input_timeout),
                ("drift_rear", "rear drift flag", f"{p}/wheel_drift/rear, the bridge", s.input_timeout),
                ("hw", "bridge status", f"{p}/hw/status", s.hw_status_timeout))
        if s.max_tilt_deg > 0:            # the tilt limit needs the IMU all the time
            ages += (("imu", "machine orientation", f"{p}/imu, an IMU on the rear frame (max_tilt_deg > 0)",
                      s.input_timeout),)
        return ages

    def _input_problems(self, now: float, arming: bool = False) -> list[str]:
        """Problems of the inputs an attempt needs all the time: joints, odometry, drift flags,
        the bridge (age, and its level unless the device's e-stop explains it). arming: the
        preflight's stricter age, arm_fresh_fraction of each timeout."""
        inp, s, out = self.inputs, self.s, []
        for name, what, src, timeout in self._timed_inputs():
            if name not in inp.values:
                out.append(f"no {what} received ({src})")
            elif inp.age(name, now, discount=not arming) > timeout:
                paused = "" if arming else inp.paused_since(name)
                paused = f", {paused:.2f} s of it a pause of the supervisor not counted" if paused else ""
                out.append(f"{what} {inp.age(name, now, discount=False):.2f} s old (timeout {timeout:g} s{paused}; "
                           f"{src})")
            elif arming and inp.age(name, now, discount=False) > timeout * s.arm_fresh_fraction:
                out.append(f"{what} {inp.age(name, now, discount=False):.2f} s old: to arm, at most {timeout * s.arm_fresh_fraction:g} s "
                           f"({s.arm_fresh_fraction:g} of its {timeout:g} s timeout, a margin before a late message "
                           f"ends the attempt; {src})")
        if "joints" in inp.values:
            j = inp.values["joints"]
            for name in ("boom", "bucket"):
                if name not in j:
                    out.append(f"joint states have no '{name}' joint; expected boom and bucket")
                elif not _finite(*j[name]):
                    out.append(f"joint '{name}' is not finite (position, velocity = {j[name]})")
        if "odom" in inp.values:
            pos, quat, v_x = inp.values["odom"]
            if not _finite(v_x):
                out.append(f"odometry v_x is not finite ({v_x!r})")
            if not _finite(*pos, *quat) or not any(quat):
                out.append(f"odometry pose is not finite (position {pos}, orientation {quat})")
        if s.max_tilt_deg > 0 and "imu" in inp.values and self._tilt(now, discount=not arming) is None:
            out.append(f"IMU orientation is not a finite, non-zero quaternion ({inp.values['imu']})")
        hw = inp.values.get("hw")
        if hw is not None and inp.age("hw", now, discount=not arming) <= s.hw_status_timeout and not hw.estop:
            if hw.level in (ERROR, STALE):
                out.append(f"bridge reports {LEVEL_NAMES[hw.level]}: {hw.message}")
        return out

    def _estop_problem(self, now: float, discount: bool = True) -> str:
        if self.inputs.estop:
            return f"emergency stop engaged ({self.s.prefix}/estop is true)"
        hw = self.inputs.values.get("hw")
        if hw is not None and hw.estop and self.inputs.age("hw", now, discount) <= self.s.hw_status_timeout:
            return "emergency stop pressed on the device (bridge status)"
        return ""

    def _compute_tip(self, now: float, discount: bool = True) -> LhdState | None:
        """The task state from the latest joints + odometry, or None when either is missing,
        stale (discount: a pause of the caller not counted) or not finite."""
        inp = self.inputs
        if any(inp.age(n, now, discount) > self.s.input_timeout for n in ("joints", "odom")):
            return None
        pos, quat, v_x = inp.values["odom"]
        j = inp.values["joints"]
        if "boom" not in j or "bucket" not in j or not _finite(*j["boom"], *j["bucket"], *pos, *quat, v_x):
            return None
        try:
            st = state_from_measurements(self.kin, pos, quat, v_x, j, bool(inp.values.get("drift_front")),
                                         bool(inp.values.get("drift_rear")))
            if self._tilt(now, discount and self.s.max_tilt_deg > 0) is not None:   # optional IMU: real age
                # the bucket's pitch with the machine's own roll and pitch (the IMU's); the tip's
                # POSITION is the odometry's as published: the ArUco node with the IMU publishes the
                # tilted pose with base_link raised about the front wheels, which puts the tip where
                # the machine has it (the controllers see the same); turning a LEVELLED pose's arm
                # here, about base_link at its floor height, would put it where it is not (the
                # machine pivots on its front wheels, its rear axle rising)
                tilted = state_from_measurements(self.kin, pos, with_tilt(quat, self._imu_q()), v_x, j,
                                                 False, False)
                st = replace(st, phi_shovel=tilted.phi_shovel)
        except ValueError:          # a zero quaternion
            return None
        return st if _finite(st.x_shovel, st.y_shovel, st.z_shovel, st.phi_shovel) else None

    def _tilt(self, now: float, discount: bool = True) -> tuple[float, float] | None:
        """(tilt, nose-down pitch), rad, from a fresh, valid IMU orientation, else None. The tilt
        is the angle of the machine's up axis from the vertical (pitch and roll together)."""
        q = self.inputs.values.get("imu")
        if q is None or self.inputs.age("imu", now, discount) > self.s.input_timeout or not _finite(*q):
            return None
        try:
            R = quat_to_mat(*self._imu_q())
        except ValueError:                # a zero quaternion
            return None
        return math.acos(max(-1.0, min(1.0, R[2, 2]))), nose_down_pitch(R)

    def _imu_q(self) -> tuple:
        """The latest IMU orientation with its mounting (Settings.imu_zero) taken off: base_link's."""
        return level_orientation(self.inputs.values["imu"], *self.s.imu_zero)

    def _tilt_problem(self, now: float, discount: bool = True) -> str:
        """With max_tilt_deg > 0: the machine tilted beyond it (the rear lifted, or on its side)."""
        t = self._tilt(now, discount) if self.s.max_tilt_deg > 0 else None
        if t is None or t[0] <= math.radians(self.s.max_tilt_deg):
            return ""
        return (f"machine tilted {math.degrees(t[0]):.1f} deg (pitch {math.degrees(t[1]):+.1f} deg, nose down +; "
                f"max_tilt_deg {self.s.max_tilt_deg:g}): the rear lifting; lower the boom")

    def preflight(self, now: float, extra: tuple[str, ...] | list[str] = ()) -> list[str]:
        """Every reason not to start an attempt now, each a sentence; [] = ready. `extra`: the
        node's own reasons (e.g. a required listener of the status that is not there yet),
        listed last."""
        out = []
        estop = self._estop_problem(now, discount=False)
        src = self.inputs.values.get("mux")
        if estop:
            out.append(estop + ": release it first")
        elif src == "estop":
            out.append(f"emergency stop engaged (the command mux reports it: {self.s.prefix}/cmd_mux/active estop): "
                       "release it first")
        if self.controller != "teleop" and src not in (None, "none", "auto", "estop"):
            out.append(f"the command mux has {src!r} selected (the gamepad's deadman held?): let go of it before "
                       f"arming a {self.controller} attempt")
        out += self._input_problems(now, arming=True)
        tilt = self._tilt_problem(now, discount=False)
        if tilt:
            out.append(tilt)
        standing = self._tilt(now, discount=False) if self.s.max_standing_tilt_deg > 0 else None
        if standing is not None and not tilt and standing[0] > math.radians(self.s.max_standing_tilt_deg):
            out.append(f"the IMU reads the standing machine tilted {math.degrees(standing[0]):.1f} deg (pitch "
                       f"{math.degrees(standing[1]):+.1f} deg, nose down +; max_standing_tilt_deg "
                       f"{self.s.max_standing_tilt_deg:g}): a machine on its wheels in the attack pose stands level; set "
                       "the IMU's mounting (imu_zero_deg of the supervisor and the ArUco node: what it reads on a level "
                       "floor, docs/real_machine.md Calibration step 9) or level the floor")
        inp, p = self.inputs, self.s.prefix
        if "slope" not in inp.values:
            out.append(f"no pile slope received ({p}/pile/slope, the LiDAR node)")
        elif self.s.slope_timeout > 0.0 and inp.age("slope", now, discount=False) > self.s.slope_timeout:
            out.append(f"pile slope {inp.age('slope', now, discount=False):.1f} s old (slope_timeout "
                       f"{self.s.slope_timeout:g} s; {p}/pile/slope, the LiDAR node): is the LiDAR node running and "
                       "seeing the pile? The slope and zones it last sent may be of another pile")
        else:
            why = self.slope_problem(inp.values["slope"])
            if why:
                out.append(why)
        zones = inp.values.get("zones")
        if inp.zones_error:
            out.append(f"pile zones invalid ({p}/pile/zones): {inp.zones_error}")
        elif zones is None:
            out.append(f"no pile zones received ({p}/pile/zones, the end-zone node)")
        tip = self._compute_tip(now, discount=False)
        if tip is not None and zones is not None and not inp.zones_error:
            where = classify(tip.x_shovel, tip.y_shovel, tip.z_shovel, zones)
            at = f"(x {tip.x_shovel:.3f}, y {tip.y_shovel:.3f}, z {tip.z_shovel:.3f} m)"
            if where == "end":
                out.append(f"bucket tip already in the end zone {at}: back the machine off to the attack pose")
            elif where == "restricted":
                out.append(f"bucket tip in the restricted zone {at}, outside the permitted zone x in "
                           f"[{zones.x_obs_start:.3f}, {min(zones.x_obs_end, zones.x_cutoff):.3f}] m, |y| <= "
                           f"{zones.y_half:.3f} m: place the machine in front of the pile")
        out += self._placement_problems(tip)
        return out + list(extra)

    def _placement_problems(self, tip) -> list[str]:
        """With max_heading_deg / max_lateral_offset set: the machine's heading (the odometry's yaw in the pile frame)
        and the bucket tip's lateral offset (`tip`: _compute_tip's, None without valid inputs) beyond them."""
        s, out = self.s, []
        odom = self.inputs.values.get("odom")
        if odom is None:
            return out                        # the missing input is a problem of its own
        if s.max_heading_deg > 0.0 and _finite(*odom[1]):
            try:
                R = quat_to_mat(*odom[1])
            except ValueError:                # a zero quaternion: a problem of its own
                return out
            yaw = math.degrees(math.atan2(R[1, 0], R[0, 0]))    # the heading, as kinematics.with_tilt takes it
            if abs(yaw) > s.max_heading_deg:
                out.append(f"machine heading {yaw:+.1f} deg off the pile's axis (max_heading_deg {s.max_heading_deg:g}, "
                           "the range the actors were trained to start from): turn it straight in front of the pile")
        if s.max_lateral_offset > 0.0 and tip is not None:
            if abs(tip.y_shovel) > s.max_lateral_offset:
                out.append(f"bucket tip {tip.y_shovel:+.3f} m off the pile's axis (max_lateral_offset "
                           f"{s.max_lateral_offset:.3f} m, the range the actors were trained to start from): move the "
                           "machine sideways in front of the pile")
        return out

    # ------------------------------------------------------------------ commands
    def arm(self, now: float, utc: str, extra: tuple[str, ...] | list[str] = ()) -> tuple[bool, str]:
        """Start attempt N (armed, running after arm_delay) if the preflight (with the node's
        `extra` reasons) passes."""
        if self.state in LIVE:
            return False, f"attempt {self.attempt.number} is already {self.state}: abort it first"
        problems = self.preflight(now, extra)
        if problems:
            return False, "not armed: " + "; ".join(problems)
        inp = self.inputs
        n = self.next_number
        self.next_number += 1
        self.attempt = Attempt(number=n, started_utc=utc, controller=self.controller, material=self.material,
                               slope_rad=float(inp.values["slope"]), zones=inp.values["zones"], armed_at=now,
                               timeout=self.timeout_for_controller, config_hash=self.s.config_hash,
                               phi_thresh=self.s.phi_thresh)
        self.attempt.last_state = self._compute_tip(now, discount=False)
        self._cell.clear()
        self._stopped_since = None
        self.state = "armed"
        note = ""
        if self.s.arm_delay == 0:
            # (the arm delay holds every source in the mux, the gamepad too: cmd_mux.ARMED)
            self._start_running(now)
        else:
            note = f", running in {self.s.arm_delay:g} s"
        return True, (f"attempt {n} armed{note}: controller {self.controller}, "
                      f"slope {math.degrees(self.attempt.slope_rad):.1f} deg, {self.material}, timeout "
                      f"{self.attempt.timeout:g} s")

    def abort(self, now: float, reason: str = "") -> tuple[bool, str]:
        if self.state not in LIVE:
            what = "no attempt yet" if self.attempt is None else f"attempt {self.attempt.number} already ended " \
                                                                  f"({self.state})"
            return False, f"nothing to abort: {what}"
        self._end(now, "aborted", reason or f"{REASONS['aborted']} ({self.s.prefix}/abort)")
        return True, f"attempt {self.attempt.number} aborted"

    def _start_problem(self, tip: LhdState) -> str:
        """Why an armed attempt must not start running after its arm delay ("": it may). The
        preflight ran at arming; during the delay the pile estimate may have moved (the end-zone
        node republishing the zones of a new pile: the twin's fault 6, an attempt armed on the
        previous pile's zones that failed 7 ms after its start) or the machine may have been
        moved. The attempt keeps the zones frozen at arming, so both are checked against them;
        such an attempt is aborted (a set-up fault), not failed (the controller never moved)."""
        a, inp = self.attempt, self.inputs
        if inp.zones_error:
            return (f"not started: the pile zones became invalid while armed ({self.s.prefix}/pile/zones: "
                    f"{inp.zones_error}); check the end-zone node and arm again")
        now_zones = inp.values.get("zones")       # the last valid zones heard
        if now_zones is not None:
            moved = {k: (getattr(a.zones, k), getattr(now_zones, k)) for k in ZONE_LIMITS
                     if abs(getattr(a.zones, k) - getattr(now_zones, k)) > self.s.zones_tolerance}
            if moved:
                what = ", ".join(f"{k} {old:.3f} -> {new:.3f} m" for k, (old, new) in moved.items())
                return (f"not started: the pile zones changed while armed ({what}); the attempt would run on the "
                        "zones of arming: check the pile estimate and arm again")
        where = classify(tip.x_shovel, tip.y_shovel, tip.z_shovel, a.zones)
        if where != "permitted":
            at = f"(x {tip.x_shovel:.3f}, y {tip.y_shovel:.3f}, z {tip.z_shovel:.3f} m)"
            return f"not started: the bucket tip is in the {where} zone {at} at the end of the arm delay; arm again"
        return ""

    def _start_running(self, now: float) -> None:
        a = self.attempt
        self.state = "running"
        a.running_at = now

    def _end(self, now: float, outcome: str, reason: str) -> None:
        a = self.attempt
        a.ended_at = now
        a.outcome = outcome
        a.reason = reason
        a.success_level, a.success = judge(outcome, None, a.phi_final, self.s.phi_thresh)
        self.state = outcome

    # ------------------------------------------------------------------ the loop
    def held_inputs(self, now: float) -> list[str]:
        """The inputs taken before a pause of the caller and not lost: their newer messages may be
        waiting in its queue, so the machine's present state is not known yet (STALL_S)."""
        inp = self.inputs                 # an optional IMU (no tilt limit) neither holds nor is discounted
        return [n for n, _, _, timeout in self._timed_inputs() if n in inp.arrival and inp.paused_since(n) > 0.0
                and inp.age(n, now, discount=True) <= timeout]

    def update(self, now: float) -> bool:
        """Check the end conditions (and the load-cell window); True when the state changed. A
        gap since the caller last ran (an update or an input taken) longer than STALL_S is a pause
        of the caller (STALL_S, Inputs.active)."""
        self.inputs.active(now)
        before = self.state
        tip = self._compute_tip(now)
        self.tip = tip
        if self.state in LIVE:
            self._update_live(now, tip)
        elif self.state in ENDED:
            self._update_load_cell(now)
        return self.state != before

    def _update_live(self, now: float, tip: LhdState | None) -> None:
        a, s, inp = self.attempt, self.s, self.inputs
        if self.state == "running":       # the drift flags at the end of each control period, up to now
            while a.running_at + (len(a.front) + 1) * s.control_dt <= now + 1e-9:
                a.front.append(bool(inp.values.get("drift_front")))
                a.rear.append(bool(inp.values.get("drift_rear")))
        if tip is not None:
            a.last_state = tip
        estop = self._estop_problem(now)
        if estop:
            self._end(now, "estop", estop)
            return
        lost = self._input_problems(now)
        if lost:
            self._end(now, "lost_input", "; ".join(lost))
            return
        if tip is None:                   # inputs fresh and finite, but no tip: a broken orientation
            self._end(now, "lost_input", "the bucket tip cannot be computed from the odometry and joint states")
            return
        # after a pause, an input whose message may still be queued: nothing that needs the
        # machine's present state is decided (the start, success) until it is taken or lost
        waiting = bool(self.held_inputs(now))
        if self.state == "armed":
            if now - a.armed_at >= s.arm_delay and not waiting:
                why = self._start_problem(tip)
                if why:
                    self._end(now, "aborted", why)
                else:
                    self._start_running(now)
            return
        cut = self._command_problem(now)
        if cut:
            self._end(now, *cut)
            return
        tilt = self._tilt_problem(now)    # a safety end: before the end zone
        if tilt:
            self._end(now, "failure", tilt)
            return
        where = classify(tip.x_shovel, tip.y_shovel, tip.z_shovel, a.zones)
        timed_out = now - a.running_at >= a.timeout
        # while waiting, only the safety ends; the period is judged once settled (not used up here)
        judge_end = not waiting and (self._period_ended(now) or timed_out)
        if where == "end" and judge_end:  # the attempt's last instant is judged too
            self._end(now, "success", REASONS["success"])
        elif where == "restricted":
            self._end(now, "failure", REASONS["failure"])
        elif timed_out:
            self._end(now, "timeout", f"{'teleop_attempt_timeout' if a.controller == 'teleop' else 'attempt_timeout'} "
                                      f"{a.timeout:g} s passed")

    def _command_problem(self, now: float) -> tuple[str, str] | None:
        """(outcome, reason) when the machine is no longer moved by the attempt's controller while
        running (inputs `hw`, HwStatus.command_stale, and `mux`, <prefix>/cmd_mux/active):
        - the bridge's watchdog timed out (no valid command for its cmd_timeout: the command mux,
          its link, or the bridge itself stalled): lost_input;
        - the mux reports the e-stop (estop), also when this node did not hear /lhd/estop itself;
        - for an autonomous controller (not teleop): the mux selected another source (the gamepad
          took over, also when its deadman was held from the arming on): aborted; or it left the
          `auto` source it had selected in this attempt for `none` (the controller's commands stopped
          coming; the mux sends zeros): lost_input; or it has not selected `auto` at all
          FIRST_COMMAND_S after running began (the controller's commands never reached the
          machine: a controller not running, or publishing elsewhere than <prefix>/cmd/auto):
          lost_input, where the attempt used to stand still until its timeout.
        The machine stood still, or someone else drove it, for part of the attempt: its figures are
        not the controller's. Before 2026-11-28 a controller stalled for 2 s drove on afterwards and
        the attempt was recorded as a success, and a gamepad held from the arming drove a whole
        "RLD" attempt (reviews' fault injections)."""
        a, inp = self.attempt, self.inputs
        hw = inp.values.get("hw")
        if hw is not None and hw.command_stale:
            return ("lost_input", "the bridge took no valid command for its cmd_timeout and stopped the machine: the "
                                  "command mux, its link to the bridge, or the bridge itself stalled or died")
        src = inp.values.get("mux")
        if src == "estop":
            return ("estop", f"emergency stop engaged (the command mux reports it: {self.s.prefix}/cmd_mux/active "
                             "estop)")
        if src is None:
            return None
        if a.controller == "teleop":
            # a teleop attempt has the operator's timeout and no takeover checks: an autonomous controller moving the
            # machine in it (a stack whose supervisor is labelled teleop while an actor runs) is not that attempt
            if src == "auto":
                return ("aborted", "an autonomous controller's commands moved a teleop attempt (cmd_mux/active: auto): "
                                   "the supervisor's controller label is teleop while a controller runs; fix the label")
            return None
        if src == "auto":
            a.auto_seen = True
        elif src != "none":
            return ("aborted", f"the operator took over: the command mux selected {src!r} over the controller")
        elif a.auto_seen:
            return ("lost_input", "the controller's commands stopped: the command mux's auto source timed out "
                                  "(cmd_mux/active: none; a mux that restarted reports none too) and the machine was "
                                  "stopped; are the controller and the mux running?")
        elif a.running_at is not None and now - a.running_at > FIRST_COMMAND_S:
            return ("lost_input", f"the controller's commands never reached the machine: the command mux did not "
                                  f"select its auto source within {FIRST_COMMAND_S:g} s of running (cmd_mux/active: "
                                  f"none); is the controller running and publishing on {self.s.prefix}/cmd/auto?")
        return None

    def _period_ended(self, now: float) -> bool:
        """Called on every update while running: True when an end_check_period has ended since
        the previous update (always with a period of 0). A tip that enters the end zone
        mid-period is judged at the period's end, as in the task, where the machine follows the
        step's command to the step's end and the state there is the final one."""
        a, dt = self.attempt, self.s.end_check_period
        if dt <= 0.0:
            return True
        ended = int(math.floor((now - a.running_at) / dt + 1e-9))
        new = ended > a.end_checks
        a.end_checks = max(a.end_checks, ended)
        return new

    # ------------------------------------------------------------------ the loaded mass
    def set_mass(self, kg, source: str = "operator") -> AttemptRow:
        """The weighed mass of the latest ended attempt; ValueError saying why not. The
        operator's scale wins over the load cell: a load-cell mass never replaces it."""
        m = check_mass(kg)
        a = self.attempt
        if a is None:
            raise ValueError("no attempt to weigh yet")
        if self.state in LIVE:
            raise ValueError(f"attempt {a.number} is {self.state}: weigh the bucket after it ends")
        if a.running_at is None:
            # ended while armed (aborted, e-stop): the bucket on the scale is an earlier attempt's, whose row
            # would keep no mass while this one got it
            raise ValueError(never_ran_refusal(a.number))
        if source == "load_cell" and a.mass_source == "operator":
            raise ValueError(f"attempt {a.number} was weighed by the operator; the load cell does not replace it")
        a.mass, a.mass_source = m, source
        a.success_level, a.success = judge(a.outcome, m, a.phi_final, self.s.phi_thresh)
        return a.row()

    def load_cell(self, kg: float, now: float) -> str:
        """A load-cell reading (kg); returns why it was dropped, or ""."""
        if not _finite(kg) or not LOAD_CELL_RANGE[0] <= kg <= LOAD_CELL_RANGE[1]:
            return (f"load-cell mass {kg!r} kg dropped: expected a finite reading in "
                    f"[{LOAD_CELL_RANGE[0]:g}, {LOAD_CELL_RANGE[1]:g}] kg")
        self._cell.append((now, float(kg)))
        while self._cell and self._cell[0][0] < now - 10.0 * self.s.mass_settle_s:
            self._cell.popleft()
        return ""

    def machine_stopped(self, now: float) -> bool:
        """Joint states fresh, and every joint of the latest slower than STOP_SPEED on the mean of its velocities
        over the last STOP_WINDOW_S of joint states, its positions there within STOP_SPREAD (all finite): robust to the
        noise of rates differentiated from sampled angles, which crosses STOP_SPEED in single messages of a still
        machine, and not fooled by a joint swinging back and forth."""
        j = self.inputs.values.get("joints")
        if j is None or self.inputs.age("joints", now) > self.s.input_timeout:
            return False
        window = [v for t, v in self.inputs.joint_history if t >= now - STOP_WINDOW_S]
        for name in j:
            samples = [v[name] for v in window if name in v]
            if not samples or not _finite(*(x for pv in samples for x in pv)):
                return False
            positions, speeds = [p for p, _ in samples], [v for _, v in samples]
            if abs(sum(speeds) / len(speeds)) >= STOP_SPEED or max(positions) - min(positions) > STOP_SPREAD:
                return False
        return True

    def _update_load_cell(self, now: float) -> None:
        """After the end: once the machine has stood still for mass_settle_s, the median of the
        load-cell readings of that window is the attempt's mass (unless already weighed)."""
        a = self.attempt
        if a is None or a.mass is not None or not self._cell:
            return
        if a.running_at is None:
            # ended while armed: nothing was loaded, and the bucket holds an earlier attempt's load (set_mass
            # refuses it: until 2026-11-29 the load cell's refusal here ended the supervisor node, exit 2)
            return
        if not self.machine_stopped(now):
            self._stopped_since = None
            return
        if self._stopped_since is None:
            self._stopped_since = now
        if now - self._stopped_since < self.s.mass_settle_s:
            return
        window = [kg for t, kg in self._cell if t >= now - self.s.mass_settle_s]
        if len(window) >= LOAD_CELL_MIN_SAMPLES:
            self.set_mass(max(0.0, statistics.median(window)), "load_cell")

    # ------------------------------------------------------------------ reporting
    def reason(self, now: float) -> str:
        if self.state == "idle":
            return f"no attempt yet: call {self.s.prefix}/arm"
        a = self.attempt
        if self.state == "armed":
            return f"armed: running in {max(0.0, a.armed_at + self.s.arm_delay - now):.1f} s"
        if self.state == "running":
            return "attempt running: the controller may command"
        return a.reason

    def status_values(self, now: float) -> dict[str, str]:
        """The keys of <prefix>/episode (the sim node's), as strings."""
        a = self.attempt
        tip = self.tip
        slope = a.slope_rad if a is not None else self.inputs.values.get("slope", math.nan)
        v = {"state": self.state, "episode": str(a.number if a is not None else 0), "controller": self.controller,
             "loaded_mass": "nan" if a is None or a.mass is None else f"{a.mass:.2f}",
             "slope_deg": f"{math.degrees(slope):.2f}" if _finite(slope) else "nan",
             "material": a.material if a is not None else self.material,
             "x_shovel": f"{tip.x_shovel:.4f}" if tip is not None else "nan",
             "z_shovel": f"{tip.z_shovel:.4f}" if tip is not None else "nan",
             "reason": self.reason(now)}
        if a is not None:
            v["bag"] = bag_name(a.number)
            # the zones frozen at arming, as the sim node's status carries its pile's: the policy
            # node holds this end zone (d_end's x_max) while the attempt runs (slope_source attempt)
            v["end_zone"] = f"{a.zones.x_min:.4f},{a.zones.x_max:.4f},{a.zones.z_min:.4f}"
            if a.running_at is not None and self.state == "running":
                v["elapsed_s"] = f"{now - a.running_at:.2f}"
        if a is not None and self.state in ENDED:
            r = a.row()
            v["ran"] = "true" if a.running_at is not None else "false"     # ended while armed: nothing to weigh
            v.update({"elapsed_s": f"{r.elapsed_s:.2f}", "front_drift_pct": f"{r.front_drift_pct:.2f}",
                      "rear_drift_pct": f"{r.rear_drift_pct:.2f}",
                      "phi_final_deg": f"{r.phi_final_deg:.2f}" if _finite(r.phi_final_deg) else "nan"})
            if a.success_level is not None:
                v["success_level"] = str(a.success_level)
            if a.success is not None:
                v["success"] = str(a.success)
            if a.mass_source:
                v["mass_source"] = a.mass_source
        return v
