"""The end zone of the real pile (ROS-free core of the end-zone node, docs/end_zone.md).

* `InputLimits.problem`: is a measured (slope, toe, residual) usable? A reason naming the
  value and what is expected, or None.
* `zones_of_pile`: Zones.for_measured_pile plus the check that the intact wedge holds at least
  m_max (else the end zone would reach the pile's back end: a density or slope that cannot be).
* `Republisher`: the first estimate is always published; later ones only when one of the
  pile-dependent x limits (x_min, x_max, x_cutoff) moved by more than the threshold from the
  one last published, so that a LiDAR at a few Hz does not make the end zone jitter. x_obs_start /
  x_obs_end move with the toe exactly like x_min; y_half, z_min and z_top are constants.
* `load_survey` / `Survey.zones`: the surveyed constant from a YAML file (the end zone, the 8
  zone limits, or a surveyed pile: slope, toe and optionally bulk density).
"""
from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, fields
from pathlib import Path

import yaml

from .pile import wedge_mass_until
from .zones import Zones, check_slope_estimate

TRACKED = ("x_min", "x_max", "x_cutoff")       # the limits the republish threshold watches
DENSITY_RANGE = (500.0, 6000.0)                 # kg/m^3: broken ore (config pile.density_*) up to solid rock lumps
ZONE_FIELDS = tuple(f.name for f in fields(Zones))
SURVEY_KEYS = ("end_zone", "x_cutoff", "zones", "slope_deg", "toe_x", "density")


def nominal_density(cfg: dict) -> float:
    """The nominal bulk density of the config: the midpoint of pile.density_min / density_max."""
    return 0.5 * (cfg["pile"]["density_min"] + cfg["pile"]["density_max"])


def density_problem(density) -> str | None:
    lo, hi = DENSITY_RANGE
    if isinstance(density, bool) or not isinstance(density, (int, float)) or not math.isfinite(density):
        return f"bulk density {density!r}: expected a number in [{lo:g}, {hi:g}] kg/m^3"
    if not lo <= density <= hi:
        return (f"bulk density {density:g} kg/m^3 outside [{lo:g}, {hi:g}] kg/m^3 "
                f"(in kg/m^3, not t/m^3: broken ore is about 3000)")
    return None


@dataclass(frozen=True)
class InputLimits:
    slope_min: float          # rad
    slope_max: float          # rad
    toe_limit: float          # m, |toe_x| above this is absurd (a wrong LiDAR pose, a wrong frame)

    def problem(self, alpha: float, toe_x: float, residual: float = 0.0) -> str | None:
        """Why a measured pile cannot give zones, or None. alpha in rad, toe_x and residual in m."""
        bad = [f"{n} = {v!r}" for n, v in (("slope (x)", alpha), ("toe x (y)", toe_x), ("residual (z)", residual))
               if not (isinstance(v, (int, float)) and math.isfinite(v))]
        if bad:
            return f"{', '.join(bad)} not finite; expected a finite slope (rad), toe x (m) and fit residual (m)"
        if residual < 0.0:
            return f"residual (z) {residual:g} m: expected the fit's RMS residual, >= 0 m"
        deg = math.degrees(alpha)
        if not 0.0 < alpha < math.pi / 2:
            return f"slope {deg:.2f} deg outside (0, 90) deg: not a pile face (is x in radians?)"
        lo, hi = math.degrees(self.slope_min), math.degrees(self.slope_max)
        if not self.slope_min <= alpha <= self.slope_max:
            return f"slope {deg:.2f} deg outside the physical range [{lo:g}, {hi:g}] deg (slope_min_deg, slope_max_deg)"
        if abs(toe_x) > self.toe_limit:
            return (f"toe x {toe_x:.3f} m: expected |toe x| <= {self.toe_limit:g} m (toe_x_limit) in the pile "
                    f"frame; check the LiDAR pose")
        return None


def zones_of_pile(alpha: float, toe_x: float, density: float, p) -> Zones:
    """Zones of the measured pile; ValueError when the intact wedge holds less than m_max."""
    held = wedge_mass_until(math.inf, alpha, p.w_pile, density, p.h_pile)
    if held < p.m_max:
        raise ValueError(f"a {math.degrees(alpha):.1f} deg wedge {p.h_pile:g} m high and {p.w_pile:g} m wide "
                         f"at {density:g} kg/m^3 holds {held:.0f} kg, less than m_max = {p.m_max:g} kg: "
                         f"no end zone inside the pile (check the bulk density)")
    return Zones.for_measured_pile(alpha, toe_x, density, p)


def zones_at_nominal_density(alpha_est: float, density: float, p) -> Zones:
    """The zones the end-zone node publishes for a LiDAR estimate alpha_est (rad) of a pile whose toe is at
    the pile frame's origin, with the nominal bulk density `density` (nominal_density: the node knows no
    other): zones_of_pile(alpha_est, 0, density, p). Nothing of the pile in front of the machine reaches
    them: not its density, not its rocks, not its voxels. ValueError where the node publishes nothing: an
    estimate outside zones.ESTIMATE_SLOPE_RANGE_DEG, or a wedge at the estimate lighter than m_max (at
    1,880 kg/m^3 steeper than about 45.6 deg). The simulator's counterpart of what the node does with a
    slope (LhdLoadingEnv's zones_nominal_density)."""
    check_slope_estimate(alpha_est)
    return zones_of_pile(alpha_est, 0.0, density, p)


def largest_change(a: Zones, b: Zones) -> float:
    """The largest move (m) of a tracked limit between two estimates."""
    return max(abs(getattr(a, n) - getattr(b, n)) for n in TRACKED)


class Republisher:
    """Decides which estimates go out; keeps the one last published."""

    def __init__(self, threshold: float):
        self.threshold = float(threshold)
        self.published: Zones | None = None

    def offer(self, zones: Zones, force: bool = False) -> bool:
        """True when `zones` must be published (and records it as published): the first one;
        one whose tracked limits moved by more than the threshold; with `force` (an operator's
        parameter change, not jitter) any change at all."""
        if self.published is None:
            self.published = zones
            return True
        if zones == self.published:
            return False
        if force or largest_change(zones, self.published) > self.threshold:
            self.published = zones
            return True
        return False


# ---------------------------------------------------------------------- surveyed constant
@dataclass(frozen=True)
class Survey:
    path: str
    zones: Zones | None = None          # given directly (end_zone [+ x_cutoff], or all 8 limits)
    alpha: float | None = None          # rad, a surveyed pile
    toe_x: float | None = None          # m
    density: float | None = None        # kg/m^3, optional

    @property
    def is_pile(self) -> bool:
        return self.zones is None

    def zones_for(self, density: float, p) -> Zones:
        """The zones this survey gives (a surveyed pile with `density`; given zones as they are)."""
        if self.zones is not None:
            return self.zones
        return zones_of_pile(self.alpha, self.toe_x, density, p)


def _number(path: str, key: str, v) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ValueError(f"surveyed_file {path}: '{key}' = {v!r}: expected a finite number")
    return float(v)


def _numbers(path: str, key: str, v, n: int, names) -> list[float]:
    if isinstance(v, dict):
        missing = [k for k in names if k not in v]
        extra = [k for k in v if k not in names]
        if missing or extra:
            raise ValueError(f"surveyed_file {path}: '{key}' needs exactly the keys {', '.join(names)}"
                             + (f" (missing {', '.join(missing)})" if missing else "")
                             + (f" (unknown {', '.join(map(str, extra))})" if extra else ""))
        v = [v[k] for k in names]
    if not isinstance(v, (list, tuple)) or len(v) != n:
        raise ValueError(f"surveyed_file {path}: '{key}' = {v!r}: expected {n} numbers [{', '.join(names)}]")
    return [_number(path, f"{key}.{k}", x) for k, x in zip(names, v)]


def load_survey(path: str, p, limits: InputLimits) -> Survey:
    """Read a surveyed end zone or pile (docs/end_zone.md, config/end_zone_surveyed.example.yaml).
    ValueError with a one-line message naming the file, the key and what is expected."""
    try:
        text = Path(path).read_text()
    except OSError as exc:
        raise ValueError(f"surveyed_file {path}: cannot read it ({exc.strerror or exc})") from None
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ValueError(f"surveyed_file {path}: not valid YAML ({' '.join(str(exc).split())})") from None
    if not isinstance(doc, dict):
        raise ValueError(f"surveyed_file {path}: expected a mapping with end_zone (or zones) or slope_deg and "
                         f"toe_x, got {type(doc).__name__}")
    for k in doc:
        if k not in SURVEY_KEYS:
            close = difflib.get_close_matches(str(k), SURVEY_KEYS, n=1)
            raise ValueError(f"surveyed_file {path}: unknown key '{k}'"
                             + (f" (did you mean '{close[0]}'?)" if close else "")
                             + f"; expected some of {', '.join(SURVEY_KEYS)}")
    given = doc.keys() & {"end_zone", "zones"}
    pile = doc.keys() & {"slope_deg", "toe_x", "density"}
    if given and pile:
        raise ValueError(f"surveyed_file {path}: give either the zones (end_zone / zones) or a surveyed pile "
                         f"(slope_deg, toe_x, density), not both (found {', '.join(sorted(given | pile))})")
    if given:
        return Survey(path=path, zones=_given_zones(path, doc, p))
    if "x_cutoff" in doc:
        raise ValueError(f"surveyed_file {path}: x_cutoff goes with end_zone; a surveyed pile gives its own")
    if "slope_deg" not in doc or "toe_x" not in doc:
        raise ValueError(f"surveyed_file {path}: expected end_zone: [x_min, x_max, z_min], zones: (8 limits), or "
                         f"a surveyed pile with slope_deg and toe_x (found {', '.join(map(str, doc)) or 'nothing'})")
    alpha = math.radians(_number(path, "slope_deg", doc["slope_deg"]))
    toe_x = _number(path, "toe_x", doc["toe_x"])
    why = limits.problem(alpha, toe_x)
    if why:
        raise ValueError(f"surveyed_file {path}: {why}")
    density = None
    if "density" in doc:
        density = _number(path, "density", doc["density"])
        why = density_problem(density)
        if why:
            raise ValueError(f"surveyed_file {path}: {why}")
    return Survey(path=path, alpha=alpha, toe_x=toe_x, density=density)


def _given_zones(path: str, doc: dict, p) -> Zones:
    end = None
    if "end_zone" in doc:
        end = _numbers(path, "end_zone", doc["end_zone"], 3, ZONE_FIELDS[:3])
    if "zones" in doc:
        if "x_cutoff" in doc:
            raise ValueError(f"surveyed_file {path}: x_cutoff is one of the 8 zones limits; give it there")
        vals = _numbers(path, "zones", doc["zones"], len(ZONE_FIELDS), ZONE_FIELDS)
        if end is not None and any(abs(a - b) > 1e-9 for a, b in zip(end, vals[:3])):
            raise ValueError(f"surveyed_file {path}: end_zone {end} disagrees with the first three zones limits "
                             f"{vals[:3]}")
    else:
        # the end zone alone: the observation zone of the paper about the toe (the origin of {M});
        # without x_cutoff no cut at the pile's back end (the observation zone's end bounds it)
        x_obs_start, x_obs_end = -p.x_init_obs, -p.x_init_obs + p.x_obs
        x_cutoff = _number(path, "x_cutoff", doc["x_cutoff"]) if "x_cutoff" in doc else x_obs_end
        vals = end + [x_cutoff, x_obs_start, x_obs_end, p.y_obs / 2.0, p.z_obs]
    try:
        z = Zones.from_list(vals)
    except ValueError as exc:
        raise ValueError(f"surveyed_file {path}: {exc}") from None
    why = z.problem_as_surveyed()
    if why:
        raise ValueError(f"surveyed_file {path}: zones: {why}")
    return z
