"""Scripted loading maneuvers (baselines and physical-sanity checks).

``scripted_action``: drive in at full speed; once the tip passes x_midgoal, lift the boom
and curl the bucket at full rate while the wheels keep pushing at a reduced speed
(``crowd``, a fraction of full speed), so the tip climbs through the face instead of
ploughing deeper. ``push_action``: full speed, arm still.
Both return normalised actions in [-1, 1]^3.
"""
from __future__ import annotations

import numpy as np

from lhd_loading_ros.task.state import LhdState

ARM_STILL = np.array([1.0, 1.0, -1.0])      # wheels full, boom still, bucket still


def scripted_action(s: LhdState, x_midgoal: float, crowd: float = 0.3, pre_curl: float = 0.2,
                    lift_on_drift: bool = False) -> np.ndarray:
    """lift_on_drift: also start lifting when a wheel drifts (the machine has stalled before
    x_midgoal, as on steep piles)."""
    if s.x_shovel < x_midgoal and not (lift_on_drift and s.drift) and s.phi_shovel < 0.02:
        return ARM_STILL.copy()
    wheels = 2.0 * crowd - 1.0  # wheels at `crowd` of full speed
    if s.phi_shovel < pre_curl:  # curl first so the bucket ends curled past 40 deg
        return np.array([wheels, 1.0, 1.0])
    return np.array([wheels, -1.0, 1.0])  # lift and curl


def push_action(s: LhdState) -> np.ndarray:
    return ARM_STILL.copy()


def run_episode(env, policy, seed: int | None = None, options: dict | None = None):
    """Run one episode with policy(state) -> action; return the EpisodeResult."""
    env.reset(seed=seed, options=options)
    while True:
        _, _, term, trunc, info = env.step(policy(env.state))
        if term or trunc:
            return info["episode_result"]
