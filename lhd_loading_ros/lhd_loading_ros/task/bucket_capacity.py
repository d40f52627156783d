"""What the bucket can hold: struck volume plus a heap at the angle of repose, as a function
of the bucket's pitch (pure python/numpy, no ROS; docs/modeling.md "Bucket capacity").

Section (bucket frame, metres, from config `machine` and the plate thickness of
task/kinematics.py, the same geometry the MJCF builds): a bottom plate whose top face runs from
the back wall's inner face H to the lip T, a back wall whose inner face rises from H to its top
edge K, and two side plates. Inside the bucket:

    H = (t/2, z_top)            T = (tip_ahead, z_top)            K = (t/2, z_top + back_h)
    inner width W = bucket_width - t

Rating conventions (SAE J742 "Capacity rating - loader bucket"; ISO 7546 "Earth-moving machinery
- loader and front loading excavator buckets - volumetric ratings"):
* strike plane: through the cutting edge (T) and the top edge of the back sheet (K); the struck
  volume V_S lies beneath it (here the triangular prism H T K x W);
* heaped (rated) volume: V_S plus the material heaped on the strike plane at a 2:1 angle of
  repose with the strike plane level. For a strike plane of length A and width W (A <= W) the
  heap is the hip roof A^2 W / 8 - A^3 / 24.
We keep the rule (a heap limited by slopes of the angle of repose rising from the rims) and
apply it at every pitch with the material's own angle of repose theta (task.bucket_repose_deg),
as the standards allow for a known material: the free surface of a cohesionless material can
nowhere be steeper than theta, and it cannot stand above a rim (material there falls off). The
largest stable load is bounded by the surface

    S(p) = min over rim points r of ( z_r + tan(theta) * |p - r|_horizontal )

(the sand-pile surface of a container: every rim point carries an inverted cone of slope theta).
The rim is the loop lip T - side edges - back edge K. In the 2-D section the lip and back edges
give S(x) = min(z_T + tan(theta)|x - x_T|, z_K + tan(theta)|x - x_K|); the side edges (on the
strike line, slope s = tan of its tilt) give z_TK(x) + d_y * sqrt(tan^2 theta - s^2) at distance
d_y from the nearer side (the envelope of their cones). They bind only above the strike plane.
Hence, with H(x) = S(x) - z_TK(x) >= 0 the 2-D heap height above the strike line,

    V(pitch) = W * A(pitch) - integral over the rim's span of loss(H(x)) dx
    A        = area of {points of the section (triangle H T K, plus the half-strip above the strike
               line when the opening faces up) with z <= S(x)}
    loss(H)  = H^2 / k            if H <= k W / 2      (k = sqrt(tan^2 theta - s^2))
             = H W - k W^2 / 4    otherwise

(the cross-width integral of min(H, k d_y) is H W - loss(H)). Tilting the bucket forward so the
strike line drops towards the lip more steeply than theta loses material over the lip; curling
it back until the back edge is the lower rim loses it over the back. Every function here is
piecewise linear in x, so the integrals are exact (trapezoid for A, Simpson for the quadratic
loss) between the breakpoints where any two of the lines meet.

Pitch: of the tip frame in the world (0 = attack pose: plate level; positive = curled back, tip
up), as task.kinematics reports phi_shovel. Whatever tilts the machine tilts the bucket too.
"""
from __future__ import annotations

import math
from itertools import combinations

import numpy as np

from lhd_loading_ros.task.kinematics import FLOOR_GAP, PLATE_T

SAE_LOADER_REPOSE_RAD = math.atan(0.5)   # SAE J742 / ISO 7546 loader rating: heap at 2:1 (26.57 deg)


def bucket_section(machine_cfg: dict) -> dict:
    """Inner section of the bucket in the bucket frame (x forward along the plate, z up along the
    back wall; origin at the bucket hinge), as the MJCF builds it (lhd_sim_node/mjcf.py):
    heel H, lip T, back top edge K (2-tuples, m), inner width W, struck area and volume."""
    mc = machine_cfg
    t = PLATE_T
    plate_z = -(mc["bucket_hinge_height"] - FLOOR_GAP - t / 2)
    z_top = plate_z + t / 2                       # plate's top face
    H = (t / 2, z_top)                            # back wall's inner face meets the plate
    T = (float(mc["bucket_tip_ahead_of_hinge"]), z_top)
    K = (t / 2, z_top + float(mc["bucket_back_height"]))
    W = float(mc["bucket_width"]) - t             # between the side plates' inner faces
    length = T[0] - H[0]
    height = K[1] - H[1]
    if not (length > 0 and height > 0 and W > 0):
        raise ValueError(f"bucket section degenerate: plate {length:g} m, back {height:g} m, width {W:g} m")
    area = 0.5 * length * height
    return {"H": H, "T": T, "K": K, "W": W, "plate_length": length, "back_height": height,
            "strike_length": math.hypot(length, height), "struck_area": area, "struck_volume": area * W,
            "level_strike_pitch": math.atan2(height, length)}


def _rot(p, c, s):
    return (p[0] * c - p[1] * s, p[0] * s + p[1] * c)


def _lines(H, T, K, tt):
    """Non-vertical lines z = a + b x of every edge and rim slope (for the breakpoints)."""
    out = []
    for P, Q in ((H, T), (H, K), (T, K)):
        dx = Q[0] - P[0]
        if abs(dx) > 1e-12:
            b = (Q[1] - P[1]) / dx
            out.append((P[1] - b * P[0], b))
    for R in (T, K):
        out.append((R[1] - tt * R[0], tt))
        out.append((R[1] + tt * R[0], -tt))
    return out


def _vertical_extent(x, tri):
    """(lo, hi) of the triangle on the vertical line at x, or None."""
    zs = []
    for P, Q in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])):
        x0, x1 = P[0], Q[0]
        if min(x0, x1) - 1e-12 <= x <= max(x0, x1) + 1e-12:
            if abs(x1 - x0) < 1e-12:
                zs.extend((P[1], Q[1]))
            else:
                zs.append(P[1] + (Q[1] - P[1]) * (x - x0) / (x1 - x0))
    if not zs:
        return None
    return min(zs), max(zs)


def heaped_volume(pitch_rad: float, machine_cfg: dict, repose_rad: float) -> float:
    """Volume (m^3) of a cohesionless material of angle of repose `repose_rad` that the bucket
    holds when its tip frame is pitched by `pitch_rad` (0 = attack pose, + = curled back):
    struck volume plus heap, each limited by free surfaces no steeper than the angle of repose
    rising from the rims (module docstring). At the pitch that levels the strike plane and a 2:1
    repose this is the SAE J742 / ISO 7546 heaped rating."""
    if not (math.isfinite(pitch_rad) and math.isfinite(repose_rad)):
        raise ValueError(f"pitch {pitch_rad!r} rad, repose {repose_rad!r} rad: expected finite angles")
    if not 0.0 < repose_rad < math.pi / 2:
        raise ValueError(f"angle of repose {math.degrees(repose_rad):g} deg: expected within (0, 90) deg")
    sec = bucket_section(machine_cfg)
    c, s = math.cos(pitch_rad), math.sin(pitch_rad)
    H, T, K = (_rot(sec[n], c, s) for n in ("H", "T", "K"))
    W = sec["W"]
    tt = math.tan(repose_rad)
    tri = (H, T, K)

    # The opening T-K faces up when its outward normal (away from H) points up.
    ex, ez = K[0] - T[0], K[1] - T[1]
    nx, nz = -ez, ex
    if nx * (H[0] - T[0]) + nz * (H[1] - T[1]) > 0:
        nx, nz = -nx, -nz
    opening_up = nz > 1e-12
    x_lo_rim, x_hi_rim = min(T[0], K[0]), max(T[0], K[0])
    strip = opening_up and x_hi_rim - x_lo_rim > 1e-12
    slope = (K[1] - T[1]) / (K[0] - T[0]) if strip else 0.0
    k2 = tt * tt - slope * slope
    heap = strip and k2 > 0.0
    k = math.sqrt(k2) if heap else 0.0

    def S(x):
        return min(T[1] + tt * abs(x - T[0]), K[1] + tt * abs(x - K[0]))

    def z_tk(x):
        return T[1] + slope * (x - T[0])

    def column(x):
        ext = _vertical_extent(x, tri)
        in_strip = strip and x_lo_rim - 1e-12 <= x <= x_hi_rim + 1e-12
        if ext is None:
            return 0.0
        lo, hi = ext
        if in_strip:
            hi = math.inf
        return max(0.0, min(hi, S(x)) - lo)

    def loss(x):
        if not heap or not (x_lo_rim <= x <= x_hi_rim):
            return 0.0
        h = max(0.0, S(x) - z_tk(x))
        return h * h / k if h <= k * W / 2 else h * W - k * W * W / 4

    lines = _lines(H, T, K, tt)
    if heap:
        lines.append((T[1] - slope * T[0] + k * W / 2, slope))   # where the heap meets the side limit
    xs = {H[0], T[0], K[0]}
    for (a1, b1), (a2, b2) in combinations(lines, 2):
        if abs(b1 - b2) > 1e-12:
            xs.add((a2 - a1) / (b1 - b2))
    x_min, x_max = min(H[0], T[0], K[0]), max(H[0], T[0], K[0])
    xs = sorted(x for x in xs if x_min <= x <= x_max)
    area = 0.0
    lost = 0.0
    for x0, x1 in zip(xs[:-1], xs[1:]):
        dx = x1 - x0
        if dx <= 1e-15:
            continue
        # interior points only: column() jumps at the strip's ends
        e = dx * 1e-9
        a, b = x0 + e, x1 - e
        area += 0.5 * (column(a) + column(b)) * dx
        lost += (loss(a) + 4.0 * loss(0.5 * (a + b)) + loss(b)) * dx / 6.0
    return max(0.0, W * area - lost)


def struck_volume(machine_cfg: dict) -> float:
    """Volume beneath the strike plane (SAE J742 / ISO 7546 struck capacity), m^3."""
    return bucket_section(machine_cfg)["struck_volume"]


def sae_heaped_volume(machine_cfg: dict) -> float:
    """SAE J742 / ISO 7546 heaped rating: strike plane level, heap at 2:1, m^3."""
    sec = bucket_section(machine_cfg)
    return heaped_volume(sec["level_strike_pitch"], machine_cfg, SAE_LOADER_REPOSE_RAD)


def fill_scale(cfg: dict) -> float:
    """The factor on the static-heap capacity (heaped_volume at task.bucket_repose_deg) that makes the
    bucket hold task.bucket_fill_factor of its SAE heaped rating with its strike plane level (the
    rating's own pose, about the 40 deg curl a loaded bucket is carried at); 1 when the fill factor
    is 0 or absent (no fill factor: the whole static heap, 1.10 of the rating, as before 2026-12-02).

    The fill factor is the handbook's loader fill factor, the share of the rated (SAE J742 heaped)
    volume a loader delivers per pass: 85-90 % in uniform aggregates of 12 mm and over (Caterpillar
    Performance Handbook, ed. 47, Tables p. 30-2), where the heap at the gravel's static repose
    would keep 110 %. Particles of 2-5 cm bridge and leave voids at the walls and the back of a
    0.39 m bucket and the heap rides lower on a moving bucket; the model scales every pitch alike
    (docs/modeling.md "Bucket capacity")."""
    t = cfg["task"]
    fill = float(t.get("bucket_fill_factor", 0.0))
    if not (math.isfinite(fill) and 0.0 <= fill <= 1.2):
        raise ValueError(f"task.bucket_fill_factor {fill!r}: expected 0 (none) or a share of the SAE heaped rating "
                         "in (0, 1.2]")
    if fill == 0.0:
        return 1.0
    sec = bucket_section(cfg["machine"])
    sae = sae_heaped_volume(cfg["machine"])
    static = heaped_volume(sec["level_strike_pitch"], cfg["machine"], math.radians(t["bucket_repose_deg"]))
    # between the struck volume (less would spill material below the strike plane) and the static heap (more
    # would stand steeper than the angle of repose): 0.75-1.10 for this bucket at 35 deg
    lo, hi = sec["struck_volume"] / sae, static / sae
    if not lo - 1e-9 <= fill <= hi + 1e-9:
        raise ValueError(f"task.bucket_fill_factor {fill:g}: this bucket holds {lo:.3f} of its SAE heaped rating struck "
                         f"and {hi:.3f} with the static heap at task.bucket_repose_deg {t['bucket_repose_deg']:g} deg; "
                         f"expected 0 (none) or a fill factor within [{lo:.3f}, {hi:.3f}]")
    return fill * sae / static


def capacity_table(cfg: dict, step_deg: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """(pitch grid in rad, capacity in m^3): the heaped volume at the material's angle of repose
    (task.bucket_repose_deg) times fill_scale (task.bucket_fill_factor of the SAE rating with the
    strike plane level), over the pitch normalisation range of the tip frame widened by 30 deg each
    side (task.phi_shovel_min_deg / max_deg), for linear interpolation in the simulator's kernel
    (clip the pitch to the grid's ends)."""
    t = cfg["task"]
    lo = t["phi_shovel_min_deg"] - 30.0
    hi = t["phi_shovel_max_deg"] + 30.0
    n = int(round((hi - lo) / step_deg)) + 1
    grid = np.radians(np.linspace(lo, hi, n))
    repose = math.radians(t["bucket_repose_deg"])
    scale = fill_scale(cfg)
    vol = np.array([heaped_volume(float(p), cfg["machine"], repose) for p in grid]) * scale
    return grid, vol
