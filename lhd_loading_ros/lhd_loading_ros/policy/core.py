"""What the policy node does at each cycle, without ROS: keep the latest inputs with their
arrival times, decide whether they can be trusted, build the paper's 12-vector with the same
core code as the environment, run the exported actor, apply the variant's deployment filter
and map to actuator units. Any doubt gives the zero command (wheels stopped, arm held),
never a guess: a missing or stale input, a NaN, no actor, or a slope outside the range the
actor was trained on (refused, not clipped into range: the actor has never seen such a pile).

DecisionCore is that one decision path (input checks, timeouts, slope refusal, bad input ->
zero command); a controller supplies only `_act`, the command from trusted inputs:
PolicyCore (the exported actor) here, TampierCore (the heuristic) in policy/tampier.py."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from lhd_loading_ros.task.actions import apply_variant_filter, to_actuator
from lhd_loading_ros.task.kinematics import ArmKinematics, state_from_measurements
from lhd_loading_ros.task.observation import build_observation
from lhd_loading_ros.task.params import TaskParams

ZERO_COMMAND = (0.0, 0.0, 0.0)
INPUTS = ("joints", "odom", "drift_front", "drift_rear", "slope", "end_zone")
SLOW_INPUTS = ("slope", "end_zone")   # once per attempt: a LiDAR at 1-5 Hz or a latched constant
RANGE_TOL_DEG = 1e-6                  # a slope published in rad at exactly a range end is inside


def slope_refusal(slope_rad: float, range_deg: tuple[float, float] | None) -> str:
    """Why a controller made for the slopes `range_deg` (deg) refuses this told slope: "" when it is
    inside (or unchecked: range None, or not a number, which the observation reports itself). The
    policy node's rule; the environment's evaluation applies the same one (env.slope_refusal)."""
    if range_deg is None or not math.isfinite(slope_rad):
        return ""
    lo, hi = range_deg
    deg = math.degrees(slope_rad)
    if lo - RANGE_TOL_DEG <= deg <= hi + RANGE_TOL_DEG:
        return ""
    return f"slope {deg:.1f} deg is outside the range the actor was trained on [{lo:g}, {hi:g}] deg: refused, not clipped"


@dataclass
class Inputs:
    """Latest value of each input and its arrival time (monotonic seconds)."""
    values: dict = field(default_factory=dict)
    arrival: dict = field(default_factory=dict)
    rejected: dict = field(default_factory=dict)     # name -> (why its last message was refused, when)

    def put(self, name: str, value, now: float) -> None:
        self.values[name] = value
        self.arrival[name] = now

    def reject(self, name: str, why: str, now: float) -> None:
        """A message of `name` that is not a usable value (wrong joint names, a quaternion that is not
        unit): not taken, and the reason joins the input's problem while it is missing or stale, so
        /diagnostics says why instead of only that it is old (a review, 2026-11-30)."""
        self.rejected[name] = (why, now)

    def _why(self, name: str) -> str:
        r = self.rejected.get(name)
        if r is None or (name in self.arrival and self.arrival[name] >= r[1]):
            return ""
        return f" (its last message was refused: {r[0]})"

    def missing(self) -> bool:
        return any(name not in self.values for name in INPUTS)

    def problems(self, now: float, timeout: float, timeouts: dict | None = None) -> list[str]:
        """What is missing or stale: each input against `timeouts[name]` if given (math.inf:
        never stale, a latched constant), else `timeout`."""
        out = []
        for name in INPUTS:
            t = (timeouts or {}).get(name, timeout)
            if name not in self.values:
                out.append(f"no {name} received yet{self._why(name)}")
            elif now - self.arrival[name] > t:
                out.append(f"{name} is {now - self.arrival[name]:.2f} s old (timeout {t} s){self._why(name)}")
        return out


@dataclass
class Decision:
    command: tuple            # (u_wheels, u_boom, u_bucket) rad/s
    observation: np.ndarray | None
    action: np.ndarray | None  # raw actor output
    reason: str               # "" when the controller decided
    kind: str = "ok"          # ok | no_actor | inputs (missing/stale) | bad_input | out_of_range | actor_output
    note: str = ""            # what the controller did, for /diagnostics (the heuristic's stage)


class DecisionCore:
    """The decision path every controller of the policy node shares: `decide` checks the inputs
    (missing, stale, slope outside `slope_range_deg`) and turns any doubt, or a ValueError of the
    controller on a bad value, into the zero command with the reason; `_act` is the controller's
    command from trusted inputs. `reset` is called before each attempt (stateful controllers)."""

    name = "controller"

    def __init__(self, p: TaskParams, kin: ArmKinematics, slope_range_deg: tuple[float, float] | None = None):
        self.p, self.kin = p, kin
        self.slope_range_deg = slope_range_deg     # the slopes the controller was made for; None: unchecked

    def unavailable(self) -> str:
        """Why this controller cannot decide at all ("" when it can)."""
        return ""

    def reset(self) -> None:
        """A new attempt begins (the actor keeps no state)."""

    def slope_refusal(self, slope_rad: float) -> str:
        """Why this slope is refused ("" when it is inside the trained range, or not a number:
        the observation reports a NaN itself)."""
        return slope_refusal(slope_rad, self.slope_range_deg)

    def decide(self, inp: Inputs, now: float, timeout: float, timeouts: dict | None = None) -> Decision:
        """`timeout` for every input, `timeouts` per input where it differs (Inputs.problems)."""
        why = self.unavailable()
        if why:
            return Decision(ZERO_COMMAND, None, None, why, "no_actor")
        bad = inp.problems(now, timeout, timeouts)
        if bad:
            return Decision(ZERO_COMMAND, None, None, "; ".join(bad), "inputs")
        refusal = self.slope_refusal(inp.values["slope"])
        if refusal:
            return Decision(ZERO_COMMAND, None, None, refusal, "out_of_range")
        try:
            return self._act(inp)
        except ValueError as exc:           # NaN / inf in an input, broken quaternion, missing joint
            return Decision(ZERO_COMMAND, None, None, f"bad input: {exc}", "bad_input")

    def _act(self, inp: Inputs) -> Decision:
        raise NotImplementedError


class PolicyCore(DecisionCore):
    name = "actor"

    def __init__(self, actor, variant: str, p: TaskParams, kin: ArmKinematics,
                 slope_range_deg: tuple[float, float] | None = None):
        if variant not in ("rld", "rlc"):
            raise ValueError(f"variant {variant!r}: expected 'rld' or 'rlc'")
        super().__init__(p, kin, slope_range_deg)
        self.actor, self.variant = actor, variant

    def unavailable(self) -> str:
        return "no actor loaded" if self.actor is None else ""

    def observation(self, inp: Inputs) -> np.ndarray:
        jpos_vel = inp.values["joints"]
        pos, quat, v_x = inp.values["odom"]
        s = state_from_measurements(self.kin, pos, quat, v_x, jpos_vel, inp.values["drift_front"],
                                    inp.values["drift_rear"])
        x_min, x_max, z_min = inp.values["end_zone"]
        return build_observation(s, inp.values["slope"], x_max, self.p)

    def _act(self, inp: Inputs) -> Decision:
        obs = self.observation(inp)             # a ValueError here: bad input (decide)
        try:
            a = np.asarray(self.actor(obs), dtype=np.float64)
        except Exception as exc:  # noqa: BLE001 - whatever the actor raises, the machine stops
            return Decision(ZERO_COMMAND, obs, None, f"actor failed: {exc}", "actor_output")
        if a.shape != (3,) or not np.isfinite(a).all():
            return Decision(ZERO_COMMAND, obs, None, f"actor gave {a.tolist()}: expected 3 finite values",
                            "actor_output")
        a_f = apply_variant_filter(np.clip(a, -1.0, 1.0), self.variant, self.p, deploy=True)
        u = to_actuator(a_f, self.p)
        return Decision(tuple(float(v) for v in u), obs, a, "")
