"""The demonstrations' teacher as a controller of the policy node (controller:=teacher), ROS-free.

The training's scripted demonstrations (learning/demonstrations.py, docs/training.md "A teacher
that knows what the actor knows") run the maneuver of policy/maneuver.py on the zones the actor is
told: arm still and wheels full until the bucket tip passes the end zone's x_min or a wheel drifts,
then curl to `pre_curl` and lift and curl at full rate with the wheels at `crowd` of full speed;
with `end_zone_stop` > 0 the wheels stop while the tip is below z_min within that distance of
x_max, so the tip rises into the end zone in place. Everything it reads is on the machine's topics:
the tip pose from odometry and joint angles (forward kinematics), the drift flags and
/lhd/pile/end_zone [x_min, x_max, z_min], the end-zone node's zones from the LiDAR's slope. It never
reads the slope itself, so it has no trained slope range to refuse; a slope estimate that is wrong
reaches it only through the end zone, as it reached the demonstrations in training.

Its setting is the training's (config `training.demo_*`, the one source of truth): the middle of
the demonstrations' crowd range, their pre-curl and their end-zone stop. In `lhd experiment paper`
this controller (`teacher`) succeeds in every cell of the slope-error sweep on 15 and 30 deg piles
(docs/evidence/told_teacher/teacher_told_zones); here it is the third baseline beside the actor and
the Tampier-style heuristic, one that a user can run on the machine without a trained actor.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from lhd_loading_ros.policy.core import Decision, DecisionCore, Inputs
from lhd_loading_ros.policy.maneuver import push_curl_action, scripted_action
from lhd_loading_ros.task.actions import rld_filter, to_actuator
from lhd_loading_ros.task.kinematics import ArmKinematics, state_from_measurements
from lhd_loading_ros.task.params import TaskParams
from lhd_loading_ros.task.state import LhdState


@dataclass(frozen=True)
class TeacherSetting:
    crowd: float           # wheel speed while lifting, share of full speed
    pre_curl: float        # rad: bucket curl before the lift
    told_zones: bool       # the simulator's teacher reads the told zones (on the machine: always)
    end_zone_stop: float   # m: wheels stop below z_min within this of x_max (0: off)
    push_curl: float = 0.0  # rad: the bucket curls this far while it pushes (0: level push; maneuver.push_curl_action)
    late_lift: float = 0.0  # share of [x_min, x_max] where a push that has not stalled starts a late lift (0: at x_min)

    @classmethod
    def from_config(cls, cfg: dict) -> "TeacherSetting":
        """config `training.demo_*`: the middle of [demo_crowd_min, demo_crowd_max], demo_pre_curl,
        demo_told_zones, demo_end_zone_stop (the last two 0 when absent). ValueError naming the key
        when a value is out of its range: load_config refuses such a file first; this guards a
        mapping built by hand."""
        t = cfg["training"]
        lo, hi = float(t["demo_crowd_min"]), float(t["demo_crowd_max"])
        if not (0.0 < lo <= hi <= 1.0):
            raise ValueError(f"training.demo_crowd_min / demo_crowd_max = {lo:g} / {hi:g}: expected "
                             "0 < demo_crowd_min <= demo_crowd_max <= 1 (shares of full wheel speed)")
        pre_curl = float(t["demo_pre_curl"])
        if not (math.isfinite(pre_curl) and 0.0 <= pre_curl <= 1.4):      # the parameter file's own range
            raise ValueError(f"training.demo_pre_curl = {pre_curl!r}: expected an angle in [0, 1.4] rad")
        stop = float(t.get("demo_end_zone_stop", 0.0))
        if not (0.0 <= stop <= 1.0):
            raise ValueError(f"training.demo_end_zone_stop = {stop:g}: expected 0 (off) to 1 m")
        push_curl = float(t.get("demo_push_curl", 0.0))
        if not (math.isfinite(push_curl) and 0.0 <= push_curl <= 1.4):
            raise ValueError(f"training.demo_push_curl = {push_curl!r}: expected an angle in [0, 1.4] rad (0: off)")
        late = float(t.get("demo_late_lift", 0.0))
        if not (math.isfinite(late) and 0.0 <= late <= 1.0):
            raise ValueError(f"training.demo_late_lift = {late!r}: expected a share of the end zone in [0, 1] (0: off)")
        return cls(0.5 * (lo + hi), pre_curl, bool(int(t.get("demo_told_zones", 0))), stop, push_curl, late)

    @property
    def pushes_curled(self) -> bool:
        """The maneuver of maneuver.push_curl_action (it keeps memory over an attempt)."""
        return self.push_curl > 0.0 or self.late_lift > 0.0

    def as_tuple(self) -> tuple[float, float, bool, float, float, float]:
        return (self.crowd, self.pre_curl, self.told_zones, self.end_zone_stop, self.push_curl, self.late_lift)


def teacher_action(s: LhdState, end_zone, setting: TeacherSetting, memory: dict | None = None) -> np.ndarray:
    """The teacher's normalised action for state s and end zone (x_min, x_max, z_min): the
    demonstrations' maneuver (learning.demonstrations.demo_action with these zones). With
    demo_push_curl or demo_late_lift set, maneuver.push_curl_action, which needs `memory` (a dict
    for the attempt, empty at its start)."""
    x_min, x_max, z_min = end_zone
    if setting.pushes_curled:
        if memory is None:
            raise ValueError("the push-curl teacher (training.demo_push_curl / demo_late_lift) needs the attempt's "
                             "memory: pass a dict, empty at the attempt's start")
        return push_curl_action(s, x_min, x_max, z_min, memory, setting.push_curl, setting.late_lift, setting.crowd,
                                setting.pre_curl, setting.end_zone_stop)
    return scripted_action(s, x_min, crowd=setting.crowd, pre_curl=setting.pre_curl, lift_on_drift=True,
                           end_zone=(x_max, z_min), end_zone_stop=setting.end_zone_stop)


def confirm_drift(s: LhdState, run: int, confirm: int, fresh: bool = True) -> tuple[LhdState, int]:
    """(s with its drift flags down unless they have been up for `confirm` decisions in a row, the new
    count). `run`: the decisions in a row before this one with a flag up; a decision on a fresh drift
    sample (`fresh`) with a flag up counts one more, one without a flag starts the count at 0, one on a
    sample already counted leaves it. confirm 1: every flag counts at once (s unchanged). Pure: the
    policy node's teacher (TeacherCore.confirmed) and the training's demonstrations
    (learning/demonstrations.demo_action, `training.demo_drift_confirm`) share it."""
    if isinstance(confirm, bool) or not isinstance(confirm, int) or confirm < 1:
        raise ValueError(f"drift_confirm = {confirm!r}: expected a whole number of decisions >= 1")
    if not s.drift:
        return s, 0
    if fresh:
        run += 1
    if confirm > 1 and run < confirm:
        return replace(s, drift=False, drift_front=False, drift_rear=False), run
    return s, run


class TeacherCore(DecisionCore):
    """The policy node's decision path (input checks, timeouts, zero command on doubt: DecisionCore)
    with the demonstrations' teacher in place of the actor. Every command follows from the current
    tip pose, drift flags and end zone, with one piece of memory: `drift_confirm` (>= 1). A drift flag
    starts the lift only once drift_confirm decisions in a row have each had a fresh drift sample
    (a new arrival on /lhd/wheel_drift/front or rear) with a flag up; a decision on the same held
    sample does not count again, and a decision that gives the zero command (stale or bad input)
    starts the count afresh. 1 is the training's teacher (the simulator's drift flags are its wheels'
    true slip). On the machine the bridge flags drift when a rim outruns the camera's v_x, and an
    attempt starts from rest: while the wheels spin up and the camera's v_x lags, both axles read as
    drifting (in the digital twin for 0.05-0.5 s, median 0.1 s, the longest when the ArUco odometry
    ran 0.3-0.4 s late on 2 cores), and one such decision made the teacher lift at the start line
    with 6-9 kg where it loads 40 (docs/baselines.md "The demonstrations' teacher as a controller").
    A stall's drift lasts for seconds. Through the RLD filter, as in `lhd experiment paper` (its
    boom and bucket commands are already full rate or still)."""

    name = "teacher"

    def __init__(self, setting: TeacherSetting, p: TaskParams, kin: ArmKinematics, drift_confirm: int = 1):
        super().__init__(p, kin, slope_range_deg=None)
        if isinstance(drift_confirm, bool) or not isinstance(drift_confirm, int) or drift_confirm < 1:
            raise ValueError(f"drift_confirm = {drift_confirm!r}: expected a whole number of decisions >= 1")
        self.setting = setting
        self.drift_confirm = drift_confirm
        self.reset()

    def reset(self) -> None:
        self.stage = "approach"
        self.memory = {}            # the push-curl maneuver's: whether and how the lift started
        self.drift_run = 0          # consecutive decisions with a fresh drift sample and a flag up
        self._drift_arrival = None  # arrival times of the drift samples the last decision used

    def decide(self, inp: Inputs, now: float, timeout: float, timeouts: dict | None = None) -> Decision:
        d = super().decide(inp, now, timeout, timeouts)
        if d.reason:                # the zero command: the machine is told to stop, the count starts again
            self.drift_run, self._drift_arrival = 0, None
            self.stage = "zero command"
        return d

    def confirmed(self, s: LhdState, arrival=None) -> LhdState:
        """s with its drift flags down until they have been up for drift_confirm decisions in a row,
        each on a fresh sample (`arrival`: the drift samples' arrival times; None: always fresh)."""
        if self.drift_confirm == 1:       # the training's teacher: every flag counts at once
            return s
        fresh = arrival is None or arrival != self._drift_arrival
        self._drift_arrival = arrival
        s, self.drift_run = confirm_drift(s, self.drift_run, self.drift_confirm, fresh)
        return s

    def _act(self, inp: Inputs) -> Decision:
        pos, quat, v_x = inp.values["odom"]
        s = state_from_measurements(self.kin, pos, quat, v_x, inp.values["joints"], inp.values["drift_front"],
                                    inp.values["drift_rear"])
        for name in ("v_x", "phi_shovel", "x_shovel", "z_shovel"):
            if not math.isfinite(getattr(s, name)):
                raise ValueError(f"state {name} = {getattr(s, name)!r}: expected a finite number")
        zone = tuple(float(v) for v in inp.values["end_zone"])
        if len(zone) != 3 or not all(math.isfinite(v) for v in zone):
            raise ValueError(f"end zone {list(zone)}: expected 3 finite values [x_min, x_max, z_min]")
        arrival = (inp.arrival.get("drift_front"), inp.arrival.get("drift_rear"))
        a = teacher_action(self.confirmed(s, arrival), zone, self.setting, self.memory)
        if a[1] < 1.0 or a[2] > -1.0:
            move = "pre-curl" if a[1] >= 1.0 else "lift and curl"
            self.stage = f"{move} in place" if a[0] <= -1.0 else move
        else:
            self.stage = "approach"
        u = to_actuator(rld_filter(np.clip(a, -1.0, 1.0), self.p), self.p)
        return Decision(tuple(float(v) for v in u), None, a, "", note=f"stage {self.stage}")


__all__ = ["TeacherSetting", "TeacherCore", "teacher_action", "confirm_drift"]
