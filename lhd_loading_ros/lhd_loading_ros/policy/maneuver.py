"""The scripted loading maneuver as a pure function of the machine's state: the simulator's
baseline and physical-sanity check (lhd_sim_node.scripted re-exports it), the training's
demonstrations (learning/demonstrations.py) and the policy node's `teacher` controller
(policy/teacher.py) all call this one function.

``scripted_action``: drive in at full speed; once the tip passes x_midgoal, lift the boom and
curl the bucket at full rate while the wheels keep pushing at a reduced speed (``crowd``, a
fraction of full speed), so the tip climbs through the face instead of ploughing deeper.
``push_action``: full speed, arm still. Both return normalised actions in [-1, 1]^3.
"""
from __future__ import annotations

import numpy as np

from lhd_loading_ros.task.state import LhdState

ARM_STILL = np.array([1.0, 1.0, -1.0])      # wheels full, boom still, bucket still


def scripted_action(s: LhdState, x_midgoal: float, crowd: float = 0.3, pre_curl: float = 0.2,
                    lift_on_drift: bool = False, end_zone: tuple[float, float] | None = None,
                    end_zone_stop: float = 0.0) -> np.ndarray:
    """lift_on_drift: also start lifting when a wheel drifts (the machine has stalled before
    x_midgoal, as on steep piles).

    end_zone = (x_max, z_min) of the end zone the maneuver is given, and end_zone_stop > 0 (m):
    while the arm moves and the tip is still below z_min within end_zone_stop of x_max, the wheels
    stop, so the tip rises into the end zone in place instead of running past its far side into
    the restricted zone. This is what lets one maneuver load a pile shallower than the end zone
    says (a slope estimate too high puts x_max short of the pile's own; docs/training.md "Where the
    slope estimate goes")."""
    if s.x_shovel < x_midgoal and not (lift_on_drift and s.drift) and s.phi_shovel < 0.02:
        return ARM_STILL.copy()
    wheels = 2.0 * crowd - 1.0  # wheels at `crowd` of full speed
    if end_zone is not None and end_zone_stop > 0.0:
        x_max, z_min = end_zone
        if s.z_shovel < z_min and s.x_shovel > x_max - end_zone_stop:
            wheels = -1.0       # wheels stopped: lift in place inside the end zone
    if s.phi_shovel < pre_curl:  # curl first so the bucket ends curled past 40 deg
        return np.array([wheels, 1.0, 1.0])
    return np.array([wheels, -1.0, 1.0])  # lift and curl


def push_action(s: LhdState) -> np.ndarray:
    return ARM_STILL.copy()


__all__ = ["ARM_STILL", "scripted_action", "push_action"]
