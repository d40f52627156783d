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

import math
from dataclasses import astuple, dataclass, fields


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
        x_min, x_max = pile.x_at_masses((p.m_min, p.m_max))
        return cls(
            x_min=x_min, x_max=x_max, z_min=p.z_min,
            x_cutoff=pile.L - p.d_cutoff, x_obs_start=-p.x_init_obs, x_obs_end=-p.x_init_obs + p.x_obs,
            y_half=p.y_obs / 2.0, z_top=p.z_obs,
        )


    @classmethod
    def for_measured_pile(cls, alpha: float, toe_x: float, density: float, p) -> "Zones":
        """Zones of a pile known only by its measured face (the real machine: LiDAR slope and toe)
        and a nominal bulk density: the intact homogeneous wedge of height p.h_pile and width
        p.w_pile whose face rises at `alpha` from the toe at x = toe_x of the pile frame {M}.
        The mass between the toe and toe_x + s is density * w * tan(alpha) * s^2 / 2, so the end
        zone's limits are s(m) = sqrt(2 m / (density w tan alpha)), capped at the wedge's depth
        L = h / tan(alpha); every other limit is the simulator's (for_pile), shifted by toe_x."""
        if not (math.isfinite(alpha) and 0.0 < alpha < math.pi / 2):
            raise ValueError(f"pile slope {alpha!r} rad: expected a finite angle in (0, pi/2)")
        if not math.isfinite(toe_x):
            raise ValueError(f"pile toe x {toe_x!r}: expected a finite number (m)")
        if not (math.isfinite(density) and density > 0.0):
            raise ValueError(f"bulk density {density!r}: expected a positive number (kg/m^3)")
        L = p.h_pile / math.tan(alpha)

        def x_at(m: float) -> float:
            return toe_x + wedge_x_at_mass(m, alpha, density, p.w_pile, p.h_pile)

        return cls(
            x_min=x_at(p.m_min), x_max=x_at(p.m_max), z_min=p.z_min, x_cutoff=toe_x + L - p.d_cutoff,
            x_obs_start=toe_x - p.x_init_obs, x_obs_end=toe_x - p.x_init_obs + p.x_obs,
            y_half=p.y_obs / 2.0, z_top=p.z_obs,
        )

    def as_list(self) -> list[float]:
        """The 8 fields in dataclass order (the /lhd/pile/zones message)."""
        return [float(v) for v in astuple(self)]

    @classmethod
    def from_list(cls, values) -> "Zones":
        """Inverse of as_list, validated: 8 finite values with x_min < x_max and
        x_obs_start < x_obs_end, y_half > 0, the end zone starting before the restricted zone
        (x_min < x_cutoff: the end zone may reach into it, as on steep piles, where the pile's 170 kg
        lie behind the cut) and its floor on or above the pile frame's floor and below the
        observation zone's top (0 <= z_min < z_top); ValueError naming what is wrong otherwise."""
        names = [f.name for f in fields(cls)]
        vals = [float(v) for v in values]
        if len(vals) != len(names):
            raise ValueError(f"zones: expected {len(names)} values [{', '.join(names)}], got {len(vals)}")
        bad = [n for n, v in zip(names, vals) if not math.isfinite(v)]
        if bad:
            raise ValueError(f"zones: {', '.join(bad)} not finite in {vals}")
        z = cls(*vals)
        if not z.x_min < z.x_max:
            raise ValueError(f"zones: x_min {z.x_min:g} must be below x_max {z.x_max:g}")
        if not z.x_obs_start < z.x_obs_end:
            raise ValueError(f"zones: x_obs_start {z.x_obs_start:g} must be below x_obs_end {z.x_obs_end:g}")
        if not z.y_half > 0.0:
            raise ValueError(f"zones: y_half {z.y_half:g} must be positive")
        if not z.x_min < z.x_cutoff:
            raise ValueError(f"zones: the end zone starts at x_min {z.x_min:g} m, at or beyond the restricted zone "
                             f"(x_cutoff {z.x_cutoff:g} m): no tip could reach it; expected x_min < x_cutoff")
        if not 0.0 <= z.z_min < z.z_top:
            raise ValueError(f"zones: the end zone's floor z_min {z.z_min:g} m must lie on or above the pile's floor "
                             f"(z = 0) and below the observation zone's top z_top {z.z_top:g} m")
        return z

    def problem_as_surveyed(self) -> str:
        """Why a set of zones given by hand (a surveyed file) cannot be the pile in front of the
        machine, beyond from_list's checks, or "": its end zone must start inside the observation
        zone (x_obs_start < x_min < x_obs_end), where the tip is observed. (The end-zone node's own
        zones from a 5-7 deg estimate start beyond it; the supervisor refuses such slopes anyway.)"""
        if not self.x_obs_start < self.x_min < self.x_obs_end:
            return (f"the end zone starts at x_min {self.x_min:g} m, outside the observation zone "
                    f"[{self.x_obs_start:g}, {self.x_obs_end:g}] m where the tip is observed; expected "
                    f"x_obs_start < x_min < x_obs_end")
        return ""


def wedge_x_at_mass(m: float, alpha: float, density: float, w: float, h: float) -> float:
    """Distance from the toe within which an intact homogeneous wedge (face slope alpha, width w,
    height h) holds mass m: the wedge holds density w tan(alpha) s^2 / 2 up to s, so
    s = sqrt(2 m / (density w tan alpha)), capped at its depth L = h / tan(alpha)."""
    tan_a = math.tan(alpha)
    return min(math.sqrt(2.0 * m / (density * w * tan_a)), h / tan_a)


# The LiDAR slope node's physical range (its and the end-zone node's slope_min_deg / slope_max_deg
# defaults): an estimate outside it publishes no zones on the machine.
ESTIMATE_SLOPE_RANGE_DEG = (5.0, 50.0)


def check_slope_estimate(alpha_est: float) -> None:
    """ValueError for a slope estimate (rad) outside ESTIMATE_SLOPE_RANGE_DEG, where the end-zone node publishes
    no zones. Compared in radians as it always was: a 15 deg pile told 5 deg (radians(15) + radians(-10), 1e-17
    below radians(5)) counts as outside, so the starred told-5 deg cells of the slope-error tables keep the
    pile's own zones, as in every committed table (the policy node refuses such a slope in any case)."""
    lo, hi = (math.radians(a) for a in ESTIMATE_SLOPE_RANGE_DEG)
    if not (math.isfinite(alpha_est) and lo <= alpha_est <= hi):
        raise ValueError(f"slope estimate {math.degrees(alpha_est) if math.isfinite(alpha_est) else alpha_est!r} deg "
                         f"outside the LiDAR's physical range [{ESTIMATE_SLOPE_RANGE_DEG[0]:g}, "
                         f"{ESTIMATE_SLOPE_RANGE_DEG[1]:g}] deg: the end-zone node publishes no zones for it")


def zones_for_slope_estimate(zones: Zones, alpha_true: float, alpha_est: float, p) -> Zones:
    """The zones the machine works with when the LiDAR estimates the face at alpha_est while it
    rises at alpha_true: the end-zone node builds them from the estimate with the wedge of
    `for_measured_pile`, so they move with the slope error. `zones` are the pile's own (for_pile);
    its x_min / x_max are scaled by the wedge's ratio s_est / s_true = sqrt(tan alpha_true /
    tan alpha_est) (s(m) = sqrt(2 m / (rho w tan alpha)) at the same mass and density, so the
    pile's own density, rocks and voxels stay in them: no error, no change), capped at the
    estimated wedge's depth L_est = h / tan alpha_est; the restricted zone starts at
    L_est - d_cutoff, as the end-zone node puts it. The observation zone, y_half, z_min and z_top
    do not depend on the slope. An estimate outside ESTIMATE_SLOPE_RANGE_DEG: ValueError (the end-zone
    node publishes nothing for it)."""
    check_slope_estimate(alpha_est)
    if not (math.isfinite(alpha_true) and 0.0 < alpha_true < math.pi / 2):
        raise ValueError(f"pile slope {alpha_true!r} rad: expected a finite angle in (0, pi/2)")
    if alpha_est == alpha_true:
        return zones
    k = math.sqrt(math.tan(alpha_true) / math.tan(alpha_est))
    L_est = p.h_pile / math.tan(alpha_est)
    return Zones(x_min=min(zones.x_min * k, L_est), x_max=min(zones.x_max * k, L_est), z_min=zones.z_min,
                 x_cutoff=L_est - p.d_cutoff, x_obs_start=zones.x_obs_start, x_obs_end=zones.x_obs_end,
                 y_half=zones.y_half, z_top=zones.z_top)


def derived_normalisers(cfg: dict) -> tuple[float, float]:
    """(d_end_max, x_obs) derived from the pile family instead of the paper's table (config
    task.normalisers_from_pile; docs/modeling.md "Normalisers from the pile geometry").

    The paper's values keep their meaning: x_max, the end of the end zone, lies farthest from the
    toe on the shallowest pile (alpha_min) of the lightest material (pile.density_min; rocks only
    make a pile heavier, so x_max nearer), x_far = wedge_x_at_mass(m_max, alpha_min, density_min).
    d_end = |x_shovel - x_max| is largest when the episode starts (tip at d_init), so
    d_end_max = x_far - d_init, and the observation zone [-x_init_obs, -x_init_obs + x_obs] reaches
    past x_far by the room the paper's own table leaves there,
    margin = x_obs - x_init_obs - d_init - d_end_max = 1.1 - 0.1 - 0.1 - 0.87 = 0.03 m:
    x_obs = x_init_obs + x_far + margin. With x_far = 0.97 m this returns the paper's 0.87 / 1.1."""
    o, e = cfg["paper"]["observation"], cfg["paper"]["episode"]
    x_far = wedge_x_at_mass(cfg["paper"]["end_zone"]["m_max"], math.radians(e["alpha_min_deg"]),
                            cfg["pile"]["density_min"], e["w_pile"], e["h_pile"])
    margin = max(0.0, o["x_obs"] - o["x_init_obs"] - e["d_init"] - o["d_end_max"])
    return x_far - e["d_init"], o["x_init_obs"] + x_far + margin


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
