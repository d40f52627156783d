"""Scripted loading maneuvers (baselines and physical-sanity checks).

The maneuver itself is lhd_loading_ros.policy.maneuver (the policy node's `teacher` controller
runs it on the machine, where this package is not installed); re-exported here for the simulator's
callers. ``run_episode`` runs one episode of the environment with any state -> action function.
"""
from __future__ import annotations

from lhd_loading_ros.policy.maneuver import ARM_STILL, push_action, scripted_action

__all__ = ["ARM_STILL", "push_action", "scripted_action", "run_episode"]


def run_episode(env, policy, seed: int | None = None, options: dict | None = None):
    """Run one episode with policy(state) -> action; return the EpisodeResult."""
    env.reset(seed=seed, options=options)
    while True:
        _, _, term, trunc, info = env.step(policy(env.state))
        if term or trunc:
            return info["episode_result"]
