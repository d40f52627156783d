"""The 12-dimensional observation of the paper (Table "Description of the components").

Order: x, y, z of the bucket tip; its pitch; v_x; I_drift; boom angle and rate; bucket
angle and rate; d_end = |x_shovel - x_max|; alpha. Normalisation:
positions to [-1, 1] over the observation zone; angles to [-1, 1] over the joint's range
of motion; joint rates to [-1, 1] over the actuator's speed limit; v_x to [-1, 1] over the
top speed; d_end / d_end_max to [0, 1]; alpha to [0, 1] over [alpha_min, alpha_max]
(x_obs and d_end_max: the paper's table, or derived from the pile family with
task.normalisers_from_pile, zones.derived_normalisers; TaskParams carries the ones in use);
I_drift in {0, 1}. Every entry is clipped to its range so the vector always lies in the
Box the environment declares.
"""
from __future__ import annotations

import math

import numpy as np

from lhd_loading_ros.task.params import TaskParams
from lhd_loading_ros.task.state import LhdState

OBS_DIM = 12
OBS_NAMES = ("x_shovel", "y_shovel", "z_shovel", "phi_shovel", "v_x", "drift", "phi_boom", "dphi_boom",
             "phi_bucket", "dphi_bucket", "d_end", "alpha")
OBS_LOW = np.array([-1, -1, -1, -1, -1, 0, -1, -1, -1, -1, 0, 0], dtype=np.float32)
OBS_HIGH = np.ones(OBS_DIM, dtype=np.float32)
_LOW = OBS_LOW.astype(np.float64)
_HIGH = OBS_HIGH.astype(np.float64)


# The constants build_observation scales by (TaskParams fields; SI units, angles in rad). An actor's
# card records them (learning/export.py); an actor run under other values sees inputs it was never
# trained on (e.g. alpha over 10-35 deg read as over 15-30), so the nodes and the CLI refuse it
# (policy.actor_file.LoadedPolicy.observation_mismatch)
NORMALISER_FIELDS = ("x_init_obs", "x_obs", "y_obs", "z_obs", "phi_shovel_min", "phi_shovel_max", "v_x_max",
                     "boom_angle_min", "boom_angle_max", "boom_min", "boom_max", "bucket_angle_min",
                     "bucket_angle_max", "bucket_min", "bucket_max", "d_end_max", "alpha_min", "alpha_max")


def normalisers(p: TaskParams) -> dict:
    """{field: value} of NORMALISER_FIELDS for these task parameters (what an actor's card records)."""
    return {f: float(getattr(p, f)) for f in NORMALISER_FIELDS}


def normaliser_differences(recorded: dict, p: TaskParams, rel_tol: float = 1e-6) -> list[tuple[str, float, float]]:
    """(field, recorded, these parameters') for each recorded constant that differs from p's."""
    here = normalisers(p)
    return [(k, float(v), here[k]) for k, v in recorded.items()
            if k in here and not math.isclose(float(v), here[k], rel_tol=rel_tol, abs_tol=1e-9)]


def _to_pm1(v: float, lo: float, hi: float) -> float:
    return 2.0 * (v - lo) / (hi - lo) - 1.0


def build_observation(s: LhdState, alpha: float, x_max: float, p: TaskParams) -> np.ndarray:
    """Observation vector (float32, shape (12,)) for state s on a pile of slope alpha whose
    end zone ends at x_max."""
    x0 = -p.x_init_obs
    boom_speed = max(abs(p.boom_min), abs(p.boom_max))
    bucket_speed = max(abs(p.bucket_min), abs(p.bucket_max))
    o = [
        _to_pm1(s.x_shovel, x0, x0 + p.x_obs),
        _to_pm1(s.y_shovel, -p.y_obs / 2, p.y_obs / 2),
        _to_pm1(s.z_shovel, 0.0, p.z_obs),
        _to_pm1(s.phi_shovel, p.phi_shovel_min, p.phi_shovel_max),
        s.v_x / p.v_x_max,
        1.0 if s.drift else 0.0,
        _to_pm1(s.phi_boom, p.boom_angle_min, p.boom_angle_max),
        s.dphi_boom / boom_speed,
        _to_pm1(s.phi_bucket, p.bucket_angle_min, p.bucket_angle_max),
        s.dphi_bucket / bucket_speed,
        abs(s.x_shovel - x_max) / p.d_end_max,
        (alpha - p.alpha_min) / (p.alpha_max - p.alpha_min),
    ]
    if not all(map(math.isfinite, o)):
        bad = [OBS_NAMES[i] for i, v in enumerate(o) if not math.isfinite(v)]
        raise ValueError(f"observation has non-finite components: {', '.join(bad)}")
    return np.clip(np.array(o), _LOW, _HIGH).astype(np.float32)
