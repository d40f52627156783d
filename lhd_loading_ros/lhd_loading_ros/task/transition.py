"""One step of the loading task as the sim node publishes it for learners (`<prefix>/rl/transition`,
std_msgs/Float64MultiArray), and its decoding. Pure: no ROS.

Why a topic of its own: the observation and the reward are what the simulator computes from its
true state (the reward needs the loaded mass, the drift flags, the tip's depth in the pile...);
rebuilding them from /odom and /joint_states would be an approximation, and training through a
sim node must see exactly what the in-process environment gives (issue 17: three episodes within
1e-6). Every field is a float64: the integers (episode, seed, step, stamp_ns < 2^53) and the
float32 observation are exact in it.

Layout (data[i]), also named in the message's layout.dim[0].label:
  0 episode      the sim node's episode index (0, 1, ...)
  1 seed         the seed the episode's pile and conditions were drawn with
  2 step         control steps taken in the episode (0: the state after reset)
  3 stamp_ns     the sim time of the state (ns), the stamp of /odom, /joint_states, /episode
  4 reward       the reward of the step that led here (0 at step 0)
  5 terminated   1: success or failure (a terminal state)
  6 truncated    1: max_steps reached without a terminal state
  7..18          the 12-dim observation (task/observation.py), as the policy sees it
  19..21         the actuator command [u_wheels, u_boom, u_bucket] (rad/s) the step was taken with (zeros at
                 step 0): a learner checks it is the one it sent, so a second publisher on <prefix>/cmd
                 (another learner, a policy node) cannot shift its transitions unnoticed
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lhd_loading_ros.task.observation import OBS_DIM

HEAD = ("episode", "seed", "step", "stamp_ns", "reward", "terminated", "truncated")
CMD_DIM = 3
SIZE = len(HEAD) + OBS_DIM + CMD_DIM
LABEL = ",".join(HEAD) + f",obs[{OBS_DIM}],command[{CMD_DIM}]"


@dataclass(frozen=True)
class Transition:
    episode: int
    seed: int
    step: int
    stamp_ns: int
    reward: float
    terminated: bool
    truncated: bool
    obs: np.ndarray          # float32 (OBS_DIM,)
    command: np.ndarray      # float64 (3,), the actuator command of the step


def encode(episode: int, seed: int, step: int, stamp_ns: int, reward: float, terminated: bool, truncated: bool,
           obs, command=(0.0, 0.0, 0.0)) -> list[float]:
    obs = np.asarray(obs, dtype=np.float64).ravel()
    if obs.shape != (OBS_DIM,):
        raise ValueError(f"observation has {obs.size} values; expected {OBS_DIM}")
    cmd = np.asarray(command, dtype=np.float64).ravel()
    if cmd.shape != (CMD_DIM,) or not np.isfinite(cmd).all():
        raise ValueError(f"command {cmd.tolist()}; expected {CMD_DIM} finite values")
    for name, v in (("episode", episode), ("seed", seed), ("step", step), ("stamp_ns", stamp_ns)):
        if not (0 <= int(v) < 2**53):
            raise ValueError(f"{name} = {v} cannot be carried exactly in a float64; expected 0 <= {name} < 2^53")
    if not (math.isfinite(reward) and np.isfinite(obs).all()):
        raise ValueError(f"reward {reward} or observation {obs.tolist()} is not finite; nothing non-finite is published")
    return [float(episode), float(seed), float(step), float(stamp_ns), float(reward),
            1.0 if terminated else 0.0, 1.0 if truncated else 0.0, *obs.tolist(), *cmd.tolist()]


def decode(data) -> Transition:
    """A Transition from a message's data; ValueError naming what is wrong (wrong length, a value
    that is not an integer where one is expected, non-finite values)."""
    d = np.asarray(data, dtype=np.float64).ravel()
    if d.shape != (SIZE,):
        raise ValueError(f"transition has {d.size} values; expected {SIZE} ({LABEL})")
    if not np.isfinite(d).all():
        raise ValueError(f"transition has non-finite values: {d.tolist()}")
    ints = d[:4]
    if (ints < 0).any() or (ints != np.floor(ints)).any():
        raise ValueError(f"transition's episode, seed, step, stamp_ns = {ints.tolist()}; expected non-negative integers")
    flags = d[5:7]
    if not np.isin(flags, (0.0, 1.0)).all():
        raise ValueError(f"transition's terminated, truncated = {flags.tolist()}; expected 0 or 1")
    return Transition(int(d[0]), int(d[1]), int(d[2]), int(d[3]), float(d[4]), bool(d[5]), bool(d[6]),
                      d[len(HEAD):len(HEAD) + OBS_DIM].astype(np.float32), d[len(HEAD) + OBS_DIM:].copy())
