"""Evaluation metrics of the paper: AR, AML, AFF, SL / ASL (appendix), success rate,
elapsed time, front and rear drift as a percentage of the episode's time."""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

SL_BANDS = ((28.0, 5), (26.0, 4), (24.0, 3), (22.0, 2), (20.0, 1))


def success_level(W: float, phi: float, phi_thresh: float) -> int:
    """Eq. success_rate_levels: 5..1 for W >= 28, 26, 24, 22, 20 kg with phi^T > phi_thresh, else 0."""
    if not phi > phi_thresh:
        return 0
    for lo, level in SL_BANDS:
        if W >= lo:
            return level
    return 0


@dataclass
class EpisodeResult:
    ret: float               # undiscounted return
    loaded: float            # W^T, kg
    phi_final: float         # phi_shovel^T, rad
    reached_end_zone: bool
    failed: bool             # restricted zone
    truncated: bool
    steps: int
    elapsed_s: float
    front_drift_pct: float
    rear_drift_pct: float
    success_level: int
    alpha_deg: float = float("nan")
    material: str = "homogeneous"
    max_tilt_deg: float = 0.0    # largest |pitch| of the machine's rear frame at the control periods' ends: the
                                 # rear lifting in a breakout (not in the paper's metrics; docs/modeling.md)
    refused: bool = False        # not run: the slope the controller was told lies outside the range it was trained
                                 # on, which the policy node refuses (zero command) and the supervisor does not arm

    @property
    def success(self) -> bool:
        """The paper's definition (experimental settings): at least 20 kg loaded and
        phi^T > phi_thresh at the end (SL >= 1); "attempts that end with a timeout and meet
        both success conditions are considered successes". An attempt that ends in the
        restricted zone is a failure, and a refused one loads nothing. end_zone_rate (aggregate)
        counts the end zone apart."""
        return not self.failed and not self.refused and self.success_level >= 1

    def to_dict(self) -> dict:
        d = asdict(self)
        d["success"] = self.success
        return d


def aggregate(results: list[EpisodeResult], bucket_capacity: float) -> dict:
    """AR, AML, AFF, ASL, success rate, elapsed time and drift over a list of episodes.

    Refused episodes (EpisodeResult.refused: told a slope outside the trained range, not run, as on
    the machine) count in `success_rate` as attempts that loaded nothing, the figure per pile placed;
    `success_rate_run` is over the attempts that ran, `refused` / `refused_rate` count them, and every
    other figure (what the loading did) is over the attempts that ran (NaN when none ran)."""
    if not results:
        raise ValueError("aggregate needs at least one episode result")
    run = [e for e in results if not e.refused]
    refused = len(results) - len(run)
    r = run
    mean = lambda xs: float(np.mean(xs)) if xs else float("nan")  # noqa: E731
    return {
        "episodes": len(results),
        "refused": refused,
        "refused_rate": refused / len(results),
        "success_rate_run": mean([1.0 if e.success else 0.0 for e in r]),
        "ar": mean([e.ret for e in r]),
        "aml": mean([e.loaded for e in r]),
        "aff": mean([e.loaded / bucket_capacity for e in r]),
        "asl": mean([e.success_level for e in r]),
        "success_rate": sum(1 for e in run if e.success) / len(results),
        "end_zone_rate": mean([1.0 if e.reached_end_zone else 0.0 for e in r]),
        "elapsed_s": mean([e.elapsed_s for e in r]),
        "front_drift_pct": mean([e.front_drift_pct for e in r]),
        "rear_drift_pct": mean([e.rear_drift_pct for e in r]),
        "max_tilt_deg": mean([e.max_tilt_deg for e in r]),
        "tilt_over_5deg_rate": mean([1.0 if e.max_tilt_deg > 5.0 else 0.0 for e in r]),
    }


def drift_pct(flags: list[bool]) -> float:
    return 100.0 * (sum(1 for f in flags if f) / len(flags)) if flags else 0.0



def result_from_status(kv: dict) -> EpisodeResult:
    """An episode's result from the sim node's /episode status values (DiagnosticStatus key ->
    string, as the node prints them: mass to 0.1 g, angles to 0.01 deg)."""
    state = kv["state"]
    return EpisodeResult(
        ret=float(kv.get("return", "nan")), loaded=float(kv["loaded_mass"]),
        phi_final=math.radians(float(kv.get("phi_final_deg", "nan"))), reached_end_zone=state == "success",
        failed=state == "failure", truncated=state == "timeout", steps=int(kv["step"]),
        elapsed_s=float(kv["elapsed_s"]), front_drift_pct=float(kv["front_drift_pct"]),
        rear_drift_pct=float(kv["rear_drift_pct"]), success_level=int(kv["success_level"]),
        alpha_deg=float(kv["slope_deg"]), material=kv["material"],
        max_tilt_deg=float(kv.get("max_tilt_deg", "nan")))
