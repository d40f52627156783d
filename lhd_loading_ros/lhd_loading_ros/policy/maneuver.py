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
PUSH_CURL_LEAD = 0.15   # m: push_curl_action curls during the push from this far before x_min
LATE_STOP_0 = 0.04      # m: after a late lift the wheels stop once x > x_max - (LATE_STOP_0 + LATE_STOP_K (z_min - z)):
LATE_STOP_K = 0.45      # the tip still has (z_min - z) to rise, and it moves forward about 0.45 m per metre it rises
LATE_LOOKAHEAD_S = 0.05 # s: the late lift starts when the tip will reach x_lift within half a control period (at full
                        # speed it moves 0.037 m a period): without, a 10 deg pile told 25 deg overshot x_max in 1 of 5
                        # (a review, 2026-11-30); a whole period costs 1.2 kg on a 15 deg pile told 30 deg


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


def push_curl_action(s: LhdState, x_min: float, x_max: float, z_min: float, memory: dict, push_curl: float,
                     late_lift: float, crowd: float, pre_curl: float, end_zone_stop: float = 0.0,
                     lift_on_drift: bool = True) -> np.ndarray:
    """The maneuver with the bucket curled while it pushes and a late lift (2026-11-30;
    docs/training.md "How much a slope told too high can give"). The level push of
    ``scripted_action`` fills the bucket to its attack-pose capacity (about 22 kg on the static heap,
    17.8 kg with the config's fill factor, docs/modeling.md "Bucket capacity") early in a 15 deg pile
    and stalls at 0.65-0.77 m; when the end zone is short of the pile's own (a slope
    estimate too high) the bucket must then rise through the face in place and comes out with what
    it holds. Here:

    * push: wheels full, boom still; from PUSH_CURL_LEAD before x_min the bucket curls up to
      ``push_curl`` rad (more capacity before it is under the material, and the lip, riding higher,
      stalls the push later);
    * the lift starts at the first drift (a stall: a steep pile), at the pitch ``push_curl`` + 0.02, or
      when the tip reaches x_lift = x_min + late_lift (x_max - x_min) without a stall (material
      shallower than the end zone says; half a control period ahead, LATE_LOOKAHEAD_S). Lifted by a
      stall or the pitch: curl to ``pre_curl``, lift and curl with the wheels at ``crowd`` of full speed, the wheels stopped below z_min within
      ``end_zone_stop`` of x_max, as ``scripted_action``. Lifted at x_lift: the wheels stay full while
      x < x_max - (LATE_STOP_0 + LATE_STOP_K (z_min - z)) and stop past it, a band that narrows as the
      tip rises (near the floor about 0.19 m, at 0.3 m 0.06 m), so the tip enters the end zone before
      its far side; from x_lift = x_min + 0.85 (x_max - x_min) on a 15 deg pile told 30 deg the bucket
      rises in place, full of what the pre-curled push cut.

    ``memory``: the caller's dict for one attempt (empty at its start): whether the lift started and
    how. On a 15 deg pile told 30 deg it loaded 33.6 kg where ``scripted_action`` loaded 26.3, and
    within 12 % of its no-error load in every cell of -15..+15 deg on 15 and 30 deg piles the nodes
    accept (docs/evidence/told_high_bound/teacher_push_curl/, on the static heap; with the fill factor
    on seed 5 of that pile 28.0 kg against the level push's 24.0, test_demonstrations)."""
    x_lift = x_min + late_lift * (x_max - x_min)
    if not memory.get("lift"):
        at_x = late_lift > 0.0 and s.x_shovel + LATE_LOOKAHEAD_S * max(s.v_x, 0.0) >= x_lift
        if at_x or (lift_on_drift and s.drift) or (push_curl > 0.0 and s.phi_shovel >= push_curl + 0.02) \
                or (late_lift <= 0.0 and s.x_shovel >= x_min):
            memory["lift"] = True
            memory["late"] = at_x and not s.drift
    if not memory.get("lift"):
        curl = push_curl > 0.0 and s.x_shovel >= x_min - PUSH_CURL_LEAD and s.phi_shovel < push_curl
        return np.array([1.0, 1.0, 1.0 if curl else -1.0])
    late = bool(memory.get("late"))
    wheels = 1.0 if late else 2.0 * crowd - 1.0
    margin = LATE_STOP_0 + LATE_STOP_K * (z_min - s.z_shovel) if late else end_zone_stop
    if margin > 0.0 and s.z_shovel < z_min and s.x_shovel > x_max - margin:
        wheels = -1.0
    if s.phi_shovel < pre_curl:
        return np.array([wheels, 1.0, 1.0])
    return np.array([wheels, -1.0, 1.0])


def push_action(s: LhdState) -> np.ndarray:
    return ARM_STILL.copy()


__all__ = ["ARM_STILL", "scripted_action", "push_curl_action", "push_action"]
