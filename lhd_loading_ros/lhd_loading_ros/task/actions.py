"""Action mapping and filters (paper: observations and actions, Eq. action_filter).

Actions are a = (a_wheels, a_boom, a_bucket) in [-1, 1]^3, mapped linearly onto the
actuator ranges: wheels [0, 2.7] rad/s, boom [-0.191, 0] rad/s (negative lifts),
bucket [0, 0.2] rad/s (positive curls back). So a_boom = +1 and a_bucket = -1 mean
"joint still".
"""
from __future__ import annotations

import math

import numpy as np

from lhd_loading_ros.task.params import TaskParams

ACT_DIM = 3
ACT_NAMES = ("wheels", "boom", "bucket")
ACTION_TOLERANCE = 1e-6


def validate_action(a) -> np.ndarray:
    """Return a as float64 array of shape (3,), or raise ValueError naming what is wrong."""
    arr = np.asarray(a, dtype=np.float64)
    if arr.shape != (ACT_DIM,):
        raise ValueError(f"action must have shape (3,) = (wheels, boom, bucket) in [-1, 1], got shape {arr.shape}")
    vals = arr.tolist()
    bad = [ACT_NAMES[i] for i, v in enumerate(vals) if not math.isfinite(v)]
    if bad:
        raise ValueError(f"action has non-finite components {bad}: {vals}; expected finite values in [-1, 1]")
    bad = [f"{ACT_NAMES[i]}={v:.6g}" for i, v in enumerate(vals) if abs(v) > 1.0 + ACTION_TOLERANCE]
    if bad:
        raise ValueError(f"action out of range: {', '.join(bad)}; expected each component in [-1, 1]")
    return np.array([min(max(v, -1.0), 1.0) for v in vals])


def hybrid_filter(a: float, threshold: float) -> float:
    """Paper Eq. action_filter: 1 if a > threshold, else -1."""
    return 1.0 if a > threshold else -1.0


def rld_filter(a: np.ndarray, p: TaskParams) -> np.ndarray:
    """RLD (hybrid) actions: wheels continuous, boom and bucket through the filter."""
    return np.array([a[0], hybrid_filter(a[1], p.rld_threshold), hybrid_filter(a[2], p.rld_threshold)])


def rlc_deploy_filter(a: np.ndarray, p: TaskParams) -> np.ndarray:
    """RLC deployment filter: a_boom > 0.6 -> 1 (boom still), a_bucket < -0.9 -> -1 (bucket still)."""
    out = np.array(a, dtype=np.float64, copy=True)
    if out[1] > p.rlc_boom_saturate:
        out[1] = 1.0
    if out[2] < p.rlc_bucket_saturate:
        out[2] = -1.0
    return out


def to_actuator(a: np.ndarray, p: TaskParams) -> np.ndarray:
    """[-1, 1]^3 -> (u_wheels, u_boom, u_bucket) in rad/s. The ends map exactly onto the
    range ends, so a_boom = 1 gives u_boom == 0.0 and a_bucket = -1 gives u_bucket == 0.0."""
    lo = (p.wheels_min, p.boom_min, p.bucket_min)
    hi = (p.wheels_max, p.boom_max, p.bucket_max)
    out = np.empty(3)
    for i in range(3):
        t = (a[i] + 1.0) / 2.0
        out[i] = hi[i] if t >= 1.0 else (lo[i] if t <= 0.0 else lo[i] + t * (hi[i] - lo[i]))
    return out


def apply_variant_filter(a: np.ndarray, variant: str, p: TaskParams, deploy: bool = False) -> np.ndarray:
    """The filter a variant uses: RLD always the hybrid filter; RLC the deployment filter
    only when deploy=True (training is continuous)."""
    if variant == "rld":
        return rld_filter(a, p)
    if variant == "rlc":
        return rlc_deploy_filter(a, p) if deploy else np.asarray(a, dtype=np.float64)
    raise ValueError(f"unknown variant {variant!r}; expected 'rld' or 'rlc'")
