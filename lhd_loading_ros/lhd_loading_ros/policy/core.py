"""What the policy node does at each cycle, without ROS: keep the latest inputs with their
arrival times, decide whether they can be trusted, build the paper's 12-vector with the same
core code as the environment, run the exported actor, apply the variant's deployment filter
and map to actuator units. Any doubt gives the zero command (wheels stopped, arm held),
never a guess."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from lhd_loading_ros.task.actions import apply_variant_filter, to_actuator
from lhd_loading_ros.task.kinematics import ArmKinematics, state_from_measurements
from lhd_loading_ros.task.observation import build_observation
from lhd_loading_ros.task.params import TaskParams

ZERO_COMMAND = (0.0, 0.0, 0.0)
INPUTS = ("joints", "odom", "drift_front", "drift_rear", "slope", "end_zone")


@dataclass
class Inputs:
    """Latest value of each input and its arrival time (monotonic seconds)."""
    values: dict = field(default_factory=dict)
    arrival: dict = field(default_factory=dict)

    def put(self, name: str, value, now: float) -> None:
        self.values[name] = value
        self.arrival[name] = now

    def missing(self) -> bool:
        return any(name not in self.values for name in INPUTS)

    def problems(self, now: float, timeout: float) -> list[str]:
        out = []
        for name in INPUTS:
            if name not in self.values:
                out.append(f"no {name} received yet")
            elif now - self.arrival[name] > timeout:
                out.append(f"{name} is {now - self.arrival[name]:.2f} s old (timeout {timeout} s)")
        return out


@dataclass
class Decision:
    command: tuple            # (u_wheels, u_boom, u_bucket) rad/s
    observation: np.ndarray | None
    action: np.ndarray | None  # raw actor output
    reason: str               # "" when the actor decided


class PolicyCore:
    def __init__(self, actor, variant: str, p: TaskParams, kin: ArmKinematics):
        if variant not in ("rld", "rlc"):
            raise ValueError(f"variant {variant!r}: expected 'rld' or 'rlc'")
        self.actor, self.variant, self.p, self.kin = actor, variant, p, kin

    def observation(self, inp: Inputs) -> np.ndarray:
        jpos_vel = inp.values["joints"]
        pos, quat, v_x = inp.values["odom"]
        s = state_from_measurements(self.kin, pos, quat, v_x, jpos_vel, inp.values["drift_front"],
                                    inp.values["drift_rear"])
        x_min, x_max, z_min = inp.values["end_zone"]
        return build_observation(s, inp.values["slope"], x_max, self.p)

    def decide(self, inp: Inputs, now: float, timeout: float) -> Decision:
        if self.actor is None:
            return Decision(ZERO_COMMAND, None, None, "no actor loaded")
        bad = inp.problems(now, timeout)
        if bad:
            return Decision(ZERO_COMMAND, None, None, "; ".join(bad))
        try:
            obs = self.observation(inp)
        except ValueError as exc:           # NaN / inf in an input, broken quaternion, missing joint
            return Decision(ZERO_COMMAND, None, None, f"bad input: {exc}")
        a = np.asarray(self.actor(obs), dtype=np.float64)
        if a.shape != (3,) or not np.isfinite(a).all():
            return Decision(ZERO_COMMAND, obs, None, f"actor gave {a.tolist()}: expected 3 finite values")
        a_f = apply_variant_filter(np.clip(a, -1.0, 1.0), self.variant, self.p, deploy=True)
        u = to_actuator(a_f, self.p)
        return Decision(tuple(float(v) for v in u), obs, a, "")
