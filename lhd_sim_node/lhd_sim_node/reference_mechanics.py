"""Independent hand-calculation references for the pile physics (issue 13), for
``lhd validate physics`` and the tests. Written from textbook soil mechanics, NOT from the
simulator: nothing here imports ``fee.py``, ``fee_kernel.py`` or ``bucket_body.py``.

Frame: the pile frame {M} in its XZ plane: x forward into the pile, z up, gravity -z. Angles
in radians, lengths in m, densities in kg/m^3, stresses in Pa, forces in N.

1. :func:`passive_wedge`: Coulomb's passive wedge in front of a blade on a sloped surface, as a
   direct 2-D vector force balance of the wedge polygon (no N-factor algebra), minimised over the
   failure-plane angle. The blade's rake ``rho`` is measured from the horizontal (world frame),
   the depth ``d`` vertically from the surface above the tip down to the tip; see
   :func:`face_frame` to convert to the face frame (depth normal to the face, rake from the face).
2. :func:`breakout`: the force to lift and the torque to curl a buried bucket: the weight of the
   material over the bucket opening plus the surcharge on it plus the shear on the vertical
   planes bounding that column (vertical-slip-surface model of anchor uplift), with the bucket
   geometry of config ``machine``.
3. :func:`bucket_capacity_iso7546` and :func:`bucket_capacity_at_pitch`: struck + heaped
   capacity of the bucket (ISO 7546, loader buckets) and its 2-D generalisation to any pitch;
   :func:`rating_density`: the loose density a bucket's rated payload implies (SAE J742 / ISO 7546:
   rated payload = heaped volume x loose density), next to handbook densities of gravel
   (:data:`GRAVEL_DENSITY`).

docs/modeling.md, section "Validation (lhd validate physics)", derives every equation.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lhd_loading_ros.task.kinematics import FLOOR_GAP, PLATE_T   # geometry only (plate thickness, floor gap)

G = 9.81
_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


@dataclass(frozen=True)
class Soil:
    gamma: float      # bulk density, kg/m^3
    phi: float        # internal friction angle, rad
    delta: float      # soil-tool friction angle, rad
    c: float = 0.0    # cohesion on the failure plane, Pa
    c_a: float = 0.0  # adhesion on the blade, Pa
    q: float = 0.0    # surcharge on the face (pressure normal to it), Pa


# ----------------------------------------------------------------------------------------- wedge
@dataclass(frozen=True)
class WedgeForce:
    P: float            # magnitude of the blade's force on the soil, N
    R: float            # reaction of the soil below the failure plane, N
    beta: float         # failure-plane angle from the horizontal, rad
    horizontal: float   # component resisting the tool's advance (+x on the soil = -x on the tool), N
    vertical: float     # component pushing the tool down (+ = down on the tool), N
    weight: float       # wedge weight, N
    area: float         # wedge cross-section, m^2


def face_frame(d_vertical: float, rho_world: float, alpha: float) -> tuple[float, float]:
    """(depth normal to the face, rake from the face) of a tip d_vertical below a face rising at
    alpha, blade at rho_world from the horizontal. Inverse: d_vertical = d_normal / cos(alpha),
    rho_world = rho_face - alpha."""
    return d_vertical * math.cos(alpha), rho_world + alpha


def wedge_at(beta: float, d: float, w: float, soil: Soil, alpha: float, rho: float) -> WedgeForce | None:
    """Force balance of the passive wedge for ONE failure angle beta. The tip is at the origin; the
    surface is z = d + x tan(alpha); the blade runs from the tip up and back along
    b = (-cos rho, sin rho) to the surface at B; the failure plane runs from the tip forward along
    f = (cos beta, sin beta) to the surface at F. Forces on the wedge TBF:
      weight      W = gamma g w |TB x TF| / 2, along -z
      surcharge   Q = q w |BF|, along the face's inward normal (sin alpha, -cos alpha)
      cohesion    C = c w |TF|, along -f (opposes the wedge rising along the failure plane)
      adhesion    A = c_a w |TB|, along -b (opposes the soil sliding up the blade)
      blade       P at delta from the blade normal (sin rho, cos rho), friction opposing the soil
                  sliding up the blade: direction (sin(rho+delta), cos(rho+delta))
      soil below  R at phi from the failure plane's normal (-sin beta, cos beta), friction against
                  the rise: direction cos(phi) n - sin(phi) f.
    P p + R r = -(W + Q + C + A) solved as a 2x2 linear system. None when the wedge does not exist
    (failure plane not reaching the surface ahead of the blade) or the solution is not compressive."""
    if d <= 0.0:
        return None
    ta = math.tan(alpha)
    b = (-math.cos(rho), math.sin(rho))
    f = (math.cos(beta), math.sin(beta))
    den_b = math.sin(rho) + math.cos(rho) * ta          # TB = d / den_b
    den_f = math.sin(beta) - math.cos(beta) * ta        # TF = d / den_f
    if den_b <= 1e-12 or den_f <= 1e-12:
        return None
    tb, tf = d / den_b, d / den_f
    B = (tb * b[0], tb * b[1])
    F = (tf * f[0], tf * f[1])
    if F[0] <= B[0]:
        return None
    area = 0.5 * abs(B[0] * F[1] - B[1] * F[0])
    W = soil.gamma * G * w * area
    Q = soil.q * w * math.hypot(F[0] - B[0], F[1] - B[1])
    C = soil.c * w * tf
    A = soil.c_a * w * tb
    # known forces on the wedge
    kx = Q * math.sin(alpha) - C * f[0] - A * b[0]
    kz = -W - Q * math.cos(alpha) - C * f[1] - A * b[1]
    s = rho + soil.delta
    px, pz = math.sin(s), math.cos(s)
    nf = (-math.sin(beta), math.cos(beta))
    rx = math.cos(soil.phi) * nf[0] - math.sin(soil.phi) * f[0]
    rz = math.cos(soil.phi) * nf[1] - math.sin(soil.phi) * f[1]
    det = px * rz - pz * rx
    if abs(det) < 1e-12:
        return None
    # P p + R r = -k  (Cramer)
    P = (-kx * rz + kz * rx) / det
    R = (px * -kz - pz * -kx) / det
    if P <= 0.0 or R <= 0.0:
        return None
    return WedgeForce(P=P, R=R, beta=beta, horizontal=P * px, vertical=P * pz, weight=W, area=area)


def passive_wedge(d: float, w: float, soil: Soil, alpha: float, rho: float, n_grid: int = 721,
                  tol: float = 1e-7) -> WedgeForce | None:
    """The passive wedge that needs the least blade force (Coulomb): min over beta of
    :func:`wedge_at`, on a grid over (alpha, pi - rho) refined by golden-section search around the
    best grid point. None when no wedge exists (d <= 0)."""
    if d <= 0.0:
        return None
    lo, hi = alpha + 1e-6, math.pi - rho - 1e-6
    if hi <= lo:
        return None
    grid = np.linspace(lo, hi, n_grid)
    vals = []
    for beta in grid:
        r = wedge_at(float(beta), d, w, soil, alpha, rho)
        vals.append(math.inf if r is None else r.P)
    k = int(np.argmin(vals))
    if not math.isfinite(vals[k]):
        return None
    a, c = float(grid[max(k - 1, 0)]), float(grid[min(k + 1, n_grid - 1)])

    def fP(beta):
        r = wedge_at(beta, d, w, soil, alpha, rho)
        return math.inf if r is None else r.P

    x1, x2 = c - _GOLDEN * (c - a), a + _GOLDEN * (c - a)
    f1, f2 = fP(x1), fP(x2)
    while c - a > tol:
        if f1 <= f2:
            c, x2, f2 = x2, x1, f1
            x1 = c - _GOLDEN * (c - a)
            f1 = fP(x1)
        else:
            a, x1, f1 = x1, x2, f2
            x2 = a + _GOLDEN * (c - a)
            f2 = fP(x2)
    best = wedge_at(0.5 * (a + c), d, w, soil, alpha, rho)
    grid_best = wedge_at(float(grid[k]), d, w, soil, alpha, rho)
    return best if best is not None and best.P <= grid_best.P else grid_best


# -------------------------------------------------------------------------------------- bucket
@dataclass(frozen=True)
class BucketGeometry:
    """Inner section of the bucket in its body frame (origin on the hinge axis, x along the floor
    towards the lip in the attack pose, z up), from config ``machine`` and the plate thickness."""
    length: float        # hinge to lip along the floor, m (bucket_tip_ahead_of_hinge)
    floor_below_hinge: float   # floor's inner (top) face below the hinge axis, m
    back_height: float   # back plate above the floor's inner face, m
    width: float         # outer width, m
    inner_width: float   # between the side plates, m
    inner_length: float  # back plate's inner face to lip, m

    @classmethod
    def from_machine(cls, mc: dict) -> "BucketGeometry":
        L = mc["bucket_tip_ahead_of_hinge"]
        return cls(length=L, floor_below_hinge=mc["bucket_hinge_height"] - FLOOR_GAP - PLATE_T,
                   back_height=mc["bucket_back_height"], width=mc["bucket_width"],
                   inner_width=mc["bucket_width"] - PLATE_T, inner_length=L - PLATE_T / 2)


def contents_centroid(hinge_xz, pitch: float, geom: BucketGeometry) -> tuple[float, float]:
    """Centroid (x, z) in {M} of the bucket's struck section (triangle heel - lip - back top), where
    the weight of what the bucket holds acts once it is out of the pile."""
    a, L, l, hb = geom.floor_below_hinge, geom.length, geom.inner_length, geom.back_height
    u, v = (L - l) + l / 3.0, -a + hb / 3.0
    c, s = math.cos(pitch), math.sin(pitch)
    return float(hinge_xz[0]) + u * c - v * s, float(hinge_xz[1]) + u * s + v * c


def pile_surface(alpha: float, h_pile: float):
    """z of the intact wedge pile's surface at x (0 before the toe, h behind the crest)."""
    ta = math.tan(alpha)
    return lambda x: np.clip(np.asarray(x, dtype=float) * ta, 0.0, h_pile)


def _plane_shear(H, soil: Soil, K: float):
    """Shear strength integrated over the height H of a vertical plane below the surface, per
    metre of plane: int_0^H (c + K (gamma g z + q) tan phi) dz."""
    H = np.maximum(H, 0.0)
    return soil.c * H + K * math.tan(soil.phi) * (0.5 * soil.gamma * G * H * H + soil.q * H)


@dataclass(frozen=True)
class Breakout:
    weight: float        # material over the bucket floor within its plan, N
    surcharge: float     # q on that plan, N
    shear_sides: float   # the two side planes, N
    shear_front: float   # the plane through the lip, N
    lift_force: float    # sum of the above (vertical), N
    curl_torque: float   # about the bucket hinge, N m
    boom_torque: float   # about the boom pivot (NaN when no pivot given), N m
    column_area: float   # cross-section of the column over the floor, m^2
    lip_depth: float     # surface above the lip, m


def breakout(hinge_xz, pitch: float, geom: BucketGeometry, surface, soil: Soil, K: float | None = None,
             pivot_xz=None, n: int = 400) -> Breakout:
    """Breakout of a buried bucket (vertical slip surface model: Majer 1955, as in Das & Shukla,
    *Earth Anchors*): to lift the bucket, the column of material over its floor (inside the bucket
    and above it, up to the surface ``surface(x)``) rises with it, with the surcharge on its top,
    and shears the material beside it along vertical planes through the side plates and the lip,
    where the shear strength is c + K sigma_v tan(phi), sigma_v = gamma g z + q, with the at-rest
    coefficient K = K0 = 1 - sin(phi) (Jaky) unless given. All resistances are vertical; for a
    rigid rotation about a point O every element at x resists with lever (x - x_O): the curl
    torque is taken about the hinge, the boom torque about the pivot.

    hinge_xz: the bucket hinge in {M}; pitch: the floor's angle from the horizontal (+ = lip up,
    curled back); pitch in [-pi/4, pi/2)."""
    if K is None:
        K = 1.0 - math.sin(soil.phi)
    xh, zh = float(hinge_xz[0]), float(hinge_xz[1])
    c, s = math.cos(pitch), math.sin(pitch)
    # floor's inner face: from the heel (back plate) to the lip, rotated by pitch about the hinge
    a = geom.floor_below_hinge

    def world(u, v):
        return xh + u * c - v * s, zh + u * s + v * c

    x0, z0 = world(geom.length - geom.inner_length, -a)
    x1, z1 = world(geom.length, -a)
    xs = np.linspace(x0, x1, n)
    zf = z0 + (z1 - z0) * (xs - x0) / (x1 - x0)
    H = np.maximum(np.asarray(surface(xs), dtype=float) - zf, 0.0)
    w = geom.width
    dx = np.diff(xs)
    trap = lambda y: float(np.sum(0.5 * (y[1:] + y[:-1]) * dx))  # noqa: E731
    col = trap(H)
    weight = soil.gamma * G * w * col
    covered = (H > 0.0).astype(float)
    surcharge = soil.q * w * trap(covered)
    side = 2.0 * trap(_plane_shear(H, soil, K))
    lip_depth = float(H[-1])
    front = w * float(_plane_shear(np.array([lip_depth]), soil, K)[0])
    lift = weight + surcharge + side + front
    per_x = soil.gamma * G * w * H + soil.q * w * covered + 2.0 * _plane_shear(H, soil, K)

    def torque(xo):
        return trap(per_x * (xs - xo)) + front * (x1 - xo)

    curl = torque(xh)
    boom = torque(float(pivot_xz[0])) if pivot_xz is not None else math.nan
    return Breakout(weight=weight, surcharge=surcharge, shear_sides=side, shear_front=front, lift_force=lift,
                    curl_torque=curl, boom_torque=boom, column_area=col, lip_depth=lip_depth)


# ------------------------------------------------------------------------------------ capacity
def bucket_capacity_iso7546(geom: BucketGeometry, repose: float = math.atan(0.5)) -> dict:
    """ISO 7546 (loaders): struck capacity V_s = section under the strike plane (lip to the top of
    the back plate) x inner width b; heaped V_h = V_s + s a^2 b / 4 - s a^3 / 12 with a the strike
    plane's length and s = tan(repose) (ISO: 1:2, s = 1/2: V_h = V_s + a^2 b / 8 - a^3 / 24)."""
    l, hb, b = geom.inner_length, geom.back_height, geom.inner_width
    struck = 0.5 * l * hb * b
    a = math.hypot(l, hb)
    s = math.tan(repose)
    heap = s * a * a * b / 4.0 - s * a ** 3 / 12.0
    return {"struck_m3": struck, "heap_m3": heap, "heaped_m3": struck + heap, "strike_length_m": a,
            "iso_pitch_rad": math.atan2(hb, l)}


def bucket_capacity_at_pitch(geom: BucketGeometry, pitch: float, repose: float, n: int = 4001) -> float:
    """Volume (m^3) the bucket holds with its floor pitched by `pitch` (0 = attack pose, + = curled
    back, valid in [0, pi/2)): in the section, material lies on the profile back top -> heel -> lip
    and below the repose lines rising at s = tan(repose) inwards from both rims (a heap never stands
    steeper than its angle of repose at an edge); times the inner width, less the hips at the two
    side plates (whose top edge is the strike line): (1/s) int (z_top - z_strike)_+^2 dx.
    At the ISO pose (strike line horizontal) this is exactly :func:`bucket_capacity_iso7546`."""
    if not 0.0 <= pitch < math.pi / 2:
        raise ValueError(f"pitch {pitch} rad outside [0, pi/2)")
    l, hb, b = geom.inner_length, geom.back_height, geom.inner_width
    c, s_ = math.cos(pitch), math.sin(pitch)
    lip = (l * c, l * s_)
    back = (-hb * s_, hb * c)
    s = math.tan(repose)
    xs = np.linspace(back[0], lip[0], n)
    on_back = xs < 0.0     # left of the heel: the back plate is the floor (only when curled back)
    floor = np.where(on_back, back[1] * np.divide(xs, back[0], out=np.zeros_like(xs), where=on_back),
                     lip[1] * xs / lip[0])
    top = np.minimum(lip[1] + s * (lip[0] - xs), back[1] + s * (xs - back[0]))
    thick = np.maximum(top - floor, 0.0)
    strike = back[1] + (lip[1] - back[1]) * (xs - back[0]) / (lip[0] - back[0])
    above = np.maximum(top - np.maximum(strike, floor), 0.0)
    dx = np.diff(xs)
    trap = lambda y: float(np.sum(0.5 * (y[1:] + y[:-1]) * dx))  # noqa: E731
    return b * trap(thick) - trap(above * above) / s


# Bulk densities of gravel, kg/m^3, from the weights-of-materials tables that loader handbooks quote
# (e.g. Caterpillar Performance Handbook; the same figures in the construction tables of
# doi:10.1201/b12981): loose, as dumped, and the 1/4-2 in (6-50 mm) grading, dry and wet. The
# paper's pile is 2-5 cm gravel, i.e. the 6-50 mm grading. Not fitted to anything here.
GRAVEL_DENSITY = {
    "dry, loose": 1522.0,
    "dry, 6-50 mm": 1682.0,
    "wet, 6-50 mm": 2002.0,
}


# Loader bucket fill factors: the share of the rated (SAE J742 / ISO 7546 heaped) volume a wheel loader
# delivers per pass, by material (Caterpillar Performance Handbook, Edition 47, Tables p. 30-2, loaders;
# the wheel-loader pages agree). The paper's pile is 2-5 cm gravel: uniform aggregate of 24 mm and over.
# Not fitted to anything here.
LOADER_FILL_FACTOR = {
    "uniform aggregates 12 mm and over": (0.85, 0.90),
    "mixed moist aggregates": (0.95, 1.00),
    "blasted rock": (0.60, 0.95),
}
COARSE_GRAVEL_FILL = LOADER_FILL_FACTOR["uniform aggregates 12 mm and over"]


# The paper's real machine pushing without lifting into a pile it could not lift out of: RLC and RLD
# told 15 deg on a 30 deg pile "end by a timeout, with the machine being stuck and trying to move
# forward without lifting the bucket" with 23.86 +- 0.70 and 25.94 +- 0.80 kg (its slope-error
# table, error -15 deg; the paper notes the bucket full). Whether they curled the bucket before is
# not said: the simulator's push with the arm still is the nearest like-for-like it has.
MACHINE_STUCK_PUSH_30DEG_KG = {"RLC": 23.86, "RLD": 25.94}


def rating_density(heaped_m3: float, rated_kg: float) -> float:
    """The loose material density at which a bucket of heaped volume `heaped_m3` (SAE J742 / ISO
    7546, 2:1 heap) holds its rated payload `rated_kg`: a loader bucket is sized so that rated
    payload = heaped volume x the loose density of the material it is rated for."""
    if not (heaped_m3 > 0.0 and rated_kg > 0.0):
        raise ValueError(f"heaped volume {heaped_m3!r} m^3 and rated payload {rated_kg!r} kg must be > 0")
    return rated_kg / heaped_m3
