"""The actuator ranges of the task's actions (config `paper.control`: wheels [0, 2.7] rad/s,
boom [-0.191, 0] rad/s (negative lifts), bucket [0, 0.2] rad/s (positive curls back)), as one
object that teleop and the command mux use to check and clamp [u_wheels, u_boom, u_bucket].

These are the same numbers `task.actions.to_actuator` maps the actor's [-1, 1] actions onto, so
no source of commands (actor, heuristic, gamepad) can ask for more than the paper's actions can.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from lhd_loading_ros.task.actions import ACT_NAMES
from lhd_loading_ros.task.params import TaskParams

ZERO = (0.0, 0.0, 0.0)


class CommandInvalid(ValueError):
    """A command that cannot be used at all (wrong length, not a number): rejected, not clamped."""


@dataclass(frozen=True)
class ActuatorLimits:
    lo: tuple[float, float, float]
    hi: tuple[float, float, float]

    @classmethod
    def from_params(cls, p: TaskParams) -> "ActuatorLimits":
        return cls((p.wheels_min, p.boom_min, p.bucket_min), (p.wheels_max, p.boom_max, p.bucket_max))

    def __post_init__(self):
        for i, name in enumerate(ACT_NAMES):
            lo, hi = self.lo[i], self.hi[i]
            if not (math.isfinite(lo) and math.isfinite(hi) and lo <= 0.0 <= hi and lo < hi):
                raise ValueError(f"actuator range of {name} [{lo}, {hi}] must be finite and contain 0 "
                                 "(the zero command must be inside every range)")

    def clamp(self, cmd) -> tuple[float, float, float]:
        return tuple(min(max(float(v), self.lo[i]), self.hi[i]) for i, v in enumerate(cmd))

    def check(self, data) -> tuple[tuple[float, float, float], bool]:
        """(the command clamped to the ranges, whether clamping changed it); CommandInvalid
        naming what is wrong for anything that is not 3 finite numbers."""
        try:
            vals = [float(v) for v in data]
        except (TypeError, ValueError):
            raise CommandInvalid(f"command {data!r} is not a list of numbers; expected [u_wheels, u_boom, u_bucket] "
                                 "rad/s") from None
        if len(vals) != 3:
            raise CommandInvalid(f"command has {len(vals)} values {vals}; expected 3: [u_wheels, u_boom, u_bucket] rad/s")
        bad = [ACT_NAMES[i] for i, v in enumerate(vals) if not math.isfinite(v)]
        if bad:
            raise CommandInvalid(f"command {vals} has non-finite {', '.join(bad)}; expected finite rad/s")
        out = self.clamp(vals)
        return out, out != tuple(vals)

    def describe(self) -> str:
        return ", ".join(f"{n} [{self.lo[i]:g}, {self.hi[i]:g}]" for i, n in enumerate(ACT_NAMES))
