"""A Tampier-style heuristic loading controller: the paper's "Tampier system" baseline, ROS-free.

Sources. Salas, Leiva and Ruiz-del-Solar compare their policies with "a system based on the
algorithm developed by" Tampier, Mascaró and Ruiz-del-Solar, "Autonomous Loading System for
Load-Haul-Dump (LHD) Machines Used in Underground Mining", Applied Sciences 11(18):8718, 2021
(https://doi.org/10.3390/app11188718), whose loading stage charges the pile and then excavates
with expert-operator rules. What the comparison paper says of that system is what this module
keeps (docs/baselines.md quotes each passage):
- the loading stage "starts when the LHD hits the muck pile at maximum speed";
- its bucket-tip curves "showcase that this method works by following sequential stages: the LHD
  first buries the bucket into the muck pile, then lifts it and keeps burying it, repeating this
  pattern until the loading maneuver is deemed as complete";
- it "generally never stops accelerating until the end of the excavation process" (hence > 90 %
  rear drift on the real machine);
- its failures came "mainly due to it failing at detecting the initial collision with the pile of
  material, which resulted in a timeout [...] since the bucket movement sequence did not trigger".
The thresholds of the original are not published in the comparison paper; the ones here are named,
explained and set in config/tampier.yaml.

The state machine, one step per control period over what the policy node measures (v_x, the joint
angles, the drift flags, the bucket tip from forward kinematics, the end zone):

  approach  wheels full, arm still. The highest v_x so far is the approach speed. The collision
            with the pile: v_x below collision_speed_fraction of it for collision_time, or a wheel
            drifting for collision_drift_time, both only once the approach speed has reached
            approach_min_speed. Nothing else triggers the sequence: a collision that is never
            detected (the speed never drops far enough, no wheel drifts) means pushing with the arm
            still until the supervisor's timeout, the real system's known weakness, kept.
  bury      wheels full, arm still, at least bury_time; then a drifting wheel or a stall (v_x below
            stall_speed_fraction of the approach speed for stall_time) starts a lift.
  lift      wheels full, boom lifting at full rate for lift_time, then
  tilt      wheels full, bucket curling at full rate for tilt_time, then bury again.
  curl      once the boom is lifted by boom_full_deg (the bucket has climbed through the face):
            wheels full, bucket curling until the tip's pitch reaches pitch_full_deg (or the
            bucket joint its end), then
  raise     wheels full, boom lifting (held from boom_top_deg on) until the tip is in the end zone.
  done      the tip reached the end zone (from any stage): zero command from then on.

Valves are ternary, as on the real machine: boom and bucket commands are full rate or zero, and
the wheels are full speed or stopped (the heuristic never eases off). Commands are actuator units,
(u_wheels, u_boom, u_bucket) rad/s, what /lhd/cmd carries.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import yaml

from lhd_loading_ros.policy.core import Decision, DecisionCore, Inputs
from lhd_loading_ros.task.config import ConfigError
from lhd_loading_ros.task.kinematics import ArmKinematics, state_from_measurements
from lhd_loading_ros.task.params import TaskParams
from lhd_loading_ros.task.state import LhdState

STAGES = ("approach", "bury", "lift", "tilt", "curl", "raise", "done")
BUCKET_END_MARGIN = 0.02     # rad: the bucket joint counts as at its end this close to task.bucket_angle_max


@dataclass(frozen=True)
class TampierParams:
    """config/tampier.yaml, section `tampier` (meaning and reasons there). Angles in degrees as
    written; times in seconds."""
    approach_min_speed: float
    collision_speed_fraction: float
    collision_time: float
    collision_drift_time: float
    bury_time: float
    stall_speed_fraction: float
    stall_time: float
    lift_time: float
    tilt_time: float
    boom_full_deg: float
    pitch_full_deg: float
    boom_top_deg: float


# (min, max, unit) of each key: physical or structural limits, not tuning advice
SCHEMA = {
    "approach_min_speed": (0.0, 5.0, "m/s"), "collision_speed_fraction": (0.0, 1.0, "of the approach speed"),
    "collision_time": (0.0, 10.0, "s"), "collision_drift_time": (0.0, 10.0, "s"), "bury_time": (0.0, 10.0, "s"),
    "stall_speed_fraction": (0.0, 1.0, "of the approach speed"), "stall_time": (0.0, 10.0, "s"),
    "lift_time": (0.0, 10.0, "s"), "tilt_time": (0.0, 10.0, "s"), "boom_full_deg": (0.0, 90.0, "deg"),
    "pitch_full_deg": (0.0, 90.0, "deg"), "boom_top_deg": (0.0, 90.0, "deg"),
}


def validate_tampier(section) -> TampierParams:
    """The `tampier` mapping as TampierParams, or ConfigError naming every wrong key."""
    if not isinstance(section, dict):
        raise ConfigError(f"'tampier' must be a mapping of keys, got {type(section).__name__}")
    errors = [f"unknown key 'tampier.{k}'; expected one of: {', '.join(SCHEMA)}" for k in section if k not in SCHEMA]
    for key, (lo, hi, unit) in SCHEMA.items():
        if key not in section:
            errors.append(f"missing key 'tampier.{key}' (a number in [{lo:g}, {hi:g}] {unit})")
            continue
        v = section[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not lo <= v <= hi:
            errors.append(f"'tampier.{key}' = {v!r}: expected a number in [{lo:g}, {hi:g}] {unit}")
    if not errors and section["boom_full_deg"] > section["boom_top_deg"]:
        errors.append("relation violated: tampier.boom_full_deg <= tampier.boom_top_deg")
    if errors:
        raise ConfigError("invalid Tampier parameters:\n  - " + "\n  - ".join(errors))
    return TampierParams(**{k: float(section[k]) for k in SCHEMA})


def default_tampier_path() -> Path:
    """$LHD_TAMPIER_CONFIG, else config/tampier.yaml of the source tree, else the installed share copy."""
    env = os.environ.get("LHD_TAMPIER_CONFIG")
    if env:
        return Path(env)
    here = Path(__file__).resolve()
    for parent in here.parents:
        cand = parent / "config" / "tampier.yaml"
        if cand.is_file():
            return cand
    try:  # colcon install: share/lhd_loading_ros/config (setup.py installs config/*.yaml)
        from ament_index_python.packages import get_package_share_directory

        cand = Path(get_package_share_directory("lhd_loading_ros")) / "config" / "tampier.yaml"
        if cand.is_file():
            return cand
    except Exception:  # noqa: BLE001 - ament index absent or package not installed there
        pass
    raise ConfigError("cannot find config/tampier.yaml: set LHD_TAMPIER_CONFIG to its path")


def load_tampier_config(path: str | os.PathLike | None = None) -> TampierParams:
    p = Path(path) if path else default_tampier_path()
    try:
        doc = yaml.safe_load(p.read_text())
    except OSError as exc:
        raise ConfigError(f"cannot read Tampier parameter file {p}: {exc}") from exc
    except yaml.YAMLError as exc:
        raise ConfigError(f"{p} is not valid YAML: {exc}") from exc
    if not isinstance(doc, dict) or set(doc) != {"tampier"}:
        raise ConfigError(f"{p}: expected one top-level section 'tampier', got "
                          f"{sorted(doc) if isinstance(doc, dict) else type(doc).__name__}")
    try:
        return validate_tampier(doc["tampier"])
    except ConfigError as exc:
        raise ConfigError(f"{p}: {exc}") from None


def periods(seconds: float, dt: float) -> int:
    """A duration as whole control periods, at least one."""
    return max(1, int(round(seconds / dt)))


def tip_in_end_zone(s: LhdState, end_zone) -> bool:
    """The bucket tip inside [x_min, x_max] x (z_min, inf): task.zones.in_end_zone's test on the
    three numbers /lhd/pile/end_zone carries."""
    x_min, x_max, z_min = end_zone
    return x_min < s.x_shovel < x_max and s.z_shovel > z_min


class TampierController:
    """The state machine (module docstring). One `step` per control period of `dt` seconds;
    `reset` before each attempt."""

    def __init__(self, tp: TampierParams, p: TaskParams, dt: float | None = None):
        self.tp, self.p = tp, p
        self.dt = p.control_dt if dt is None else dt
        if not (math.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"control period {self.dt!r} s: expected a positive number")
        self.n_collision = periods(tp.collision_time, self.dt)
        self.n_collision_drift = periods(tp.collision_drift_time, self.dt)
        self.n_bury = periods(tp.bury_time, self.dt)
        self.n_stall = periods(tp.stall_time, self.dt)
        self.n_lift = periods(tp.lift_time, self.dt)
        self.n_tilt = periods(tp.tilt_time, self.dt)
        self.boom_full = math.radians(tp.boom_full_deg)
        self.boom_top = math.radians(tp.boom_top_deg)
        self.pitch_full = math.radians(tp.pitch_full_deg)
        self.reset()

    def reset(self) -> None:
        self.stage = "approach"
        self.v_approach = 0.0          # highest v_x of the attempt so far
        self.slow = 0                  # consecutive periods below the collision speed
        self.drifting = 0              # consecutive periods with a drifting wheel
        self.stalled = 0               # consecutive periods below the stall speed
        self.in_stage = 0              # periods spent in the current stage
        self.collision_step = None     # the step at which the collision was detected
        self.steps = 0
        self.history: list[str] = []   # stage of each step, for tests and plots

    # ternary commands (rad/s): full rate or nothing
    def _cmd(self, wheels: bool, lift: bool, curl: bool) -> tuple:
        p = self.p
        return (p.wheels_max if wheels else 0.0, p.boom_min if lift else 0.0, p.bucket_max if curl else 0.0)

    def _go(self, stage: str) -> None:
        self.stage, self.in_stage = stage, 0

    def step(self, s: LhdState, end_zone) -> tuple:
        """The command for this period (u_wheels, u_boom, u_bucket) rad/s; self.stage says why."""
        for name in ("v_x", "phi_boom", "phi_bucket", "phi_shovel", "x_shovel", "z_shovel"):
            if not math.isfinite(getattr(s, name)):
                raise ValueError(f"state {name} = {getattr(s, name)!r}: expected a finite number")
        self.steps += 1
        self.v_approach = max(self.v_approach, s.v_x)
        drift = bool(s.drift_front or s.drift_rear or s.drift)
        self.drifting = self.drifting + 1 if drift else 0
        self.stalled = self.stalled + 1 if s.v_x < self.tp.stall_speed_fraction * self.v_approach else 0
        lifted = -s.phi_boom                     # boom: negative = lifted
        if self.stage == "approach":
            at_speed = self.v_approach >= self.tp.approach_min_speed
            self.slow = self.slow + 1 if at_speed and s.v_x < self.tp.collision_speed_fraction * self.v_approach else 0
            if self.slow >= self.n_collision or (at_speed and self.drifting >= self.n_collision_drift):
                self.collision_step = self.steps
                self._go("bury")
        if self.stage != "done" and tip_in_end_zone(s, end_zone):
            self._go("done")
        if self.stage in ("bury", "lift", "tilt") and lifted >= self.boom_full:
            self._go("curl")
        if self.stage == "curl" and (s.phi_shovel >= self.pitch_full
                                     or s.phi_bucket >= self.p.bucket_angle_max - BUCKET_END_MARGIN):
            self._go("raise")
        if self.stage == "bury" and self.in_stage >= self.n_bury and (drift or self.stalled >= self.n_stall):
            self._go("lift")
        elif self.stage == "lift" and self.in_stage >= self.n_lift:
            self._go("tilt")
        elif self.stage == "tilt" and self.in_stage >= self.n_tilt:
            self._go("bury")
        self.in_stage += 1
        self.history.append(self.stage)
        return {
            "approach": lambda: self._cmd(True, False, False),
            "bury": lambda: self._cmd(True, False, False),
            "lift": lambda: self._cmd(True, True, False),
            "tilt": lambda: self._cmd(True, False, True),
            "curl": lambda: self._cmd(True, False, True),
            "raise": lambda: self._cmd(True, lifted < self.boom_top, False),
            "done": lambda: self._cmd(False, False, False),
        }[self.stage]()


class TampierCore(DecisionCore):
    """The policy node's decision path (input checks, timeouts, zero command on doubt: DecisionCore)
    with the Tampier state machine in place of the actor."""

    name = "tampier"

    def __init__(self, tp: TampierParams, p: TaskParams, kin: ArmKinematics, dt: float | None = None):
        super().__init__(p, kin, slope_range_deg=None)
        self.controller = TampierController(tp, p, dt)

    def reset(self) -> None:
        self.controller.reset()

    def _act(self, inp: Inputs) -> Decision:
        pos, quat, v_x = inp.values["odom"]
        s = state_from_measurements(self.kin, pos, quat, v_x, inp.values["joints"], inp.values["drift_front"],
                                    inp.values["drift_rear"])
        if not math.isfinite(inp.values["slope"]):
            raise ValueError(f"slope {inp.values['slope']!r}: expected a finite angle")
        zone = tuple(inp.values["end_zone"])
        if not all(math.isfinite(v) for v in zone):
            raise ValueError(f"end zone {list(zone)}: expected 3 finite values [x_min, x_max, z_min]")
        u = self.controller.step(s, zone)
        return Decision(tuple(float(v) for v in u), None, None, "", note=f"stage {self.controller.stage}")


__all__ = ["STAGES", "TampierParams", "TampierController", "TampierCore", "load_tampier_config",
           "validate_tampier", "default_tampier_path", "tip_in_end_zone", "periods"]
