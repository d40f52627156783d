"""Zones of the draw point in the XZ plane of the pile frame {M} (paper Fig. zones).

* end zone: x_min < x < x_max and z > z_min; x_min / x_max are where the intact pile
  holds m_min / m_max between its toe and x. Reaching it ends the episode: success.
* permitted zone: the observation zone's extent along x and y (x from -x_init_obs to
  -x_init_obs + x_obs, |y| <= y_obs/2), cut at x_cutoff = L - d_cutoff (the pile's back
  end minus d_cutoff): the bucket must not dig deeper than that. There is no height limit
  (like the end zone, the paper gives none); lifting early is what r_traj and r_midgoal
  discourage.
* restricted zone: everything else. Entering it ends the episode: failure.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Zones:
    x_min: float
    x_max: float
    z_min: float
    x_cutoff: float
    x_obs_start: float
    x_obs_end: float
    y_half: float
    z_top: float

    @classmethod
    def for_pile(cls, pile, p) -> "Zones":
        """Zones of a freshly generated pile (VoxelPile) with TaskParams p."""
        return cls(
            x_min=pile.x_at_mass(p.m_min), x_max=pile.x_at_mass(p.m_max), z_min=p.z_min,
            x_cutoff=pile.L - p.d_cutoff, x_obs_start=-p.x_init_obs, x_obs_end=-p.x_init_obs + p.x_obs,
            y_half=p.y_obs / 2.0, z_top=p.z_obs,
        )


def in_end_zone(x: float, z: float, zones: Zones) -> bool:
    return (zones.x_min < x < zones.x_max) and (z > zones.z_min)


def in_permitted_zone(x: float, y: float, z: float, zones: Zones) -> bool:
    return (zones.x_obs_start <= x <= min(zones.x_obs_end, zones.x_cutoff)
            and abs(y) <= zones.y_half)


def in_restricted_zone(x: float, y: float, z: float, zones: Zones) -> bool:
    return not in_end_zone(x, z, zones) and not in_permitted_zone(x, y, z, zones)


def classify(x: float, y: float, z: float, zones: Zones) -> str:
    """'end', 'permitted' or 'restricted' (the end zone wins where they overlap)."""
    if in_end_zone(x, z, zones):
        return "end"
    if in_permitted_zone(x, y, z, zones):
        return "permitted"
    return "restricted"
