"""The FEE (Fundamental Earth-moving Equation) in the frame of the face ahead of the lip.

The numpy reference of the simulator's pile resistance; ``fee_kernel.py`` computes the
same numbers compiled (``test_fee_kernel`` / ``test_fee_face`` check the two against each
other).

Why a face frame
----------------
Luengo, Singh & Cannon (1998) extend McKyes/Reece's FEE to a surface inclined at alpha by
writing the wedge in the world frame with a vertical depth; their weight and surcharge
factors carry (cot beta - tan alpha), which vanishes at beta = 90 deg - alpha although the
wedge there is not empty, so the failure-angle search found ever smaller forces as the face
steepened (issue 13: 333 N on flat ground, 125 N on a 35 deg face at 0.10 m depth). Here the
wedge is written where McKyes's derivation holds, in a frame whose s axis runs up the local
surface ahead of the lip (inclined at alpha_s in the world's XZ plane) and whose n axis is
the surface's outward normal:

* depth d: normal to the surface, d = d_v cos(alpha_s) for a vertical depth d_v;
* rake rho: the blade's angle to the surface, rho = rho_world + alpha_s (a blade at 60 deg to
  the floor stands at 90 deg to a 30 deg face);
* the wedge (McKyes's, the Coulomb passive wedge): the triangle between the tip, the point
  where the blade meets the surface and the point where the failure plane (at beta to the
  surface) meets it; area d^2 (cot(beta) + cot(rho)) / 2, top length d (cot(beta) + cot(rho)).
  The soil between the blade and the surface normal is part of the wedge (Reece's wedge,
  bounded by the normal, leaves it out and gave 0.73 of the Coulomb wedge on flat ground);
  for a blade leaning over the face (rho > 90 deg) cot(rho) < 0 and the overhang is taken out;
* surcharge q: normal to the surface, on the wedge's top: Q = q w d (cot(beta) + cot(rho));
* gravity: exact in the rotated frame, g (-sin alpha_s, -cos alpha_s) in (s, n): its
  component along the surface points down-slope, towards the blade, and adds to the force.

Force balance of the wedge (unknowns: the tool force P at delta from the blade's normal and
the failure-plane reaction R at phi from the plane's normal; cohesion c on the failure plane
(length d / sin beta), adhesion c_a on the blade (length d / sin rho), both opposing the
wedge's motion up and out):

    P p + R r = C t + A b + (W sin alpha_s, W cos alpha_s + Q)

    p = (sin(rho + delta), cos(rho + delta)),  r = (-sin(beta + phi), cos(beta + phi)),
    t = (cos beta, sin beta),                  b = (-cos rho, sin rho)

Eliminating R (Cramer's rule, det[p, r] = sin(rho + delta + beta + phi)):

    F = P = w (d^2 gamma g N_gamma + c d N_c + q d N_q + c_a d N_a)

    D       = cos(rho + delta) + sin(rho + delta) cot(beta + phi)
    N_gamma = (cot(beta) + cot(rho)) (cos alpha_s + sin alpha_s cot(beta + phi)) / (2 D)
    N_c     = (1 + cot(beta) cot(beta + phi)) / D
    N_q     = (cot(beta) + cot(rho)) / D
    N_a     = (1 - cot(rho) cot(beta + phi)) / D

At alpha_s = 0 these are McKyes/Reece's factors (``test_fee.py``'s flat-ground wedge balance).
beta is the angle that needs the least force (Coulomb's passive wedge): the minimum over the
failure-angle grid, restricted to admissible wedges, D > 0 (i.e. rho + delta + beta + phi <
180 deg: the tool force can push the wedge along the failure plane) and a wedge with a top,
cot(beta) + cot(rho) > 0.

A blade leaning far over the face (rho + delta + phi close to 180 deg) leaves only thin
wedges and the force grows without bound (the wedge locks). The rake relative to the face is
therefore clipped so that failure angles up to BETA_LOCK remain admissible:
rho <= 180 deg - delta - phi - BETA_LOCK, and from below to the simulator's rake_min.

Back in the world frame the tool's reaction -P p becomes

    (F_x, F_z) = -F (sin(rho - alpha_s + delta), cos(rho - alpha_s + delta))

i.e. horizontal F sin(rho_w + delta) against the motion, vertical F cos(rho_w + delta)
downward, with rho_w = rho - alpha_s the (possibly clipped) blade angle in the world.

The local surface and the lip column (per slice) are documented at :func:`lip_column` and
:func:`surface_fit`.

rho: rake, delta: soil-tool friction, phi: internal friction, beta: failure-plane angle,
alpha: slope of the surface ahead of the lip, d: depth (normal), w: slice width,
gamma: density [kg/m^3], c: cohesion [Pa], c_a: adhesion [Pa], q: surcharge [Pa].
Angles in radians; functions broadcast over numpy arrays.
"""
from __future__ import annotations

import math

import numpy as np

G = 9.81
_EPS = 1e-9

# Failure-angle grid: 1..89 degrees. 128 points give a minimum within 0.2 % of a
# 20,000-point search over the same range (test_fee checks this).
BETA_GRID = np.radians(np.linspace(1.0, 89.0, 128))
# Thinnest failure wedge that must stay admissible when the blade leans over the face (rad).
BETA_LOCK = math.radians(5.0)
# Lip column: a column counts as material ahead of the lip when its top is more than LIP_EPS
# above the lip (a layer thinner than this is below the 2-5 cm grain of the gravel and is what
# the lip itself cut, then rolled back over); at most LIP_SEARCH columns are searched.
LIP_EPS = 0.005
LIP_SEARCH = 3
# ... and only a column whose near edge lies at most half a column plus LIP_REACH ahead of the lip: the
# search is for the few mm of a roll-back, not for a face the lip has not reached. Without it the lip in
# a cut trench met 67-78 % of the at-face force with the face 4-6 cm ahead of it, and stalled 2 cm short of
# the face it never touched (a review, 2026-11-29, twelfth session; test_fee_lip_reach)
LIP_REACH = 0.01
# Surface window: the slope ahead of the lip is fitted over the column tops within
# WINDOW_DEPTHS vertical depths ahead of the lip column (the top of a wedge with
# beta ~ 18 deg: d cot(beta) = 3 d), at least 2 and at most WINDOW_MAX columns.
WINDOW_DEPTHS = 3.0
WINDOW_MAX = 16
# The fitted slope is clipped to +-SLOPE_MAX (steeper faces appear only transiently on the
# voxel grid, e.g. the step of a cut; no gravel face stands steeper than its repose angle).
SLOPE_MAX = math.radians(60.0)


def n_factors(beta, alpha, rho, delta, phi):
    """(N_gamma, N_c, N_q, N_a, D) in the face frame (broadcast): alpha = slope of the surface
    (the tilt of gravity in the face frame), rho = rake relative to the surface."""
    cot_bp = 1.0 / np.tan(beta + phi)
    cot_b = 1.0 / np.tan(beta)
    s = rho + delta
    D = np.cos(s) + np.sin(s) * cot_bp
    top = cot_b + 1.0 / np.tan(rho)  # wedge top length / d: failure plane's part + the blade's part
    n_gamma = top * (np.cos(alpha) + np.sin(alpha) * cot_bp) / (2.0 * D)
    n_c = (1.0 + cot_b * cot_bp) / D
    n_q = top / D
    n_a = (1.0 - (1.0 / np.tan(rho)) * cot_bp) / D
    return n_gamma, n_c, n_q, n_a, D


def fee_force(beta, d, w, gamma, c, q, c_a, alpha, rho, delta, phi):
    """FEE magnitude F [N] for a given failure angle beta (no minimisation); d normal depth,
    rho the rake relative to the surface."""
    n_gamma, n_c, n_q, n_a, _ = n_factors(beta, alpha, rho, delta, phi)
    return w * (d * d * gamma * G * n_gamma + c * d * n_c + q * d * n_q + c_a * d * n_a)


def fee_min(d, w, gamma, c, q, c_a, alpha, rho, delta, phi, beta_grid=BETA_GRID):
    """Minimise the FEE over the failure angle for a batch of tools (face frame).

    All arguments except ``beta_grid`` are 1-D arrays of equal length n (or scalars).
    Returns (F [n], beta* [n]). Entries with d <= 0, or without an admissible wedge, give F = 0.
    """
    d = np.atleast_1d(np.asarray(d, dtype=float))
    args = [np.atleast_1d(np.asarray(a, dtype=float))[:, None] if np.ndim(a) else a
            for a in (w, gamma, c, q, c_a, alpha, rho, delta, phi)]
    w_, gamma_, c_, q_, ca_, alpha_, rho_, delta_, phi_ = args
    dd = np.maximum(d, 0.0)[:, None]
    b = beta_grid[None, :]
    n_gamma, n_c, n_q, n_a, D = n_factors(b, alpha_, rho_, delta_, phi_)
    F = w_ * (dd * dd * gamma_ * G * n_gamma + c_ * dd * n_c + q_ * dd * n_q + ca_ * dd * n_a)
    F = np.where((D > _EPS) & (1.0 / np.tan(b) + 1.0 / np.tan(rho_) > _EPS), F, np.inf)
    idx = np.argmin(F, axis=1)
    rows = np.arange(F.shape[0])
    f_min = F[rows, idx]
    f_min = np.where(np.isfinite(f_min), f_min, 0.0)
    f_min = np.where(d > 0.0, np.maximum(f_min, 0.0), 0.0)
    return f_min, beta_grid[idx]


def face_rake(rake_world, alpha_s, delta, phi, rake_lo):
    """Rake relative to the surface, rho_world + alpha_s, clipped to
    [rake_lo, 180 deg - delta - phi - BETA_LOCK] (see the module docstring)."""
    return min(max(rake_world + alpha_s, rake_lo), math.pi - delta - phi - BETA_LOCK)


def tool_force_components(F, rake_world, delta):
    """World components of the FEE force on the tool: (horizontal, against the motion;
    vertical, positive = downward) for the blade at rake_world to the floor. With the face
    rake rho and the slope alpha_s, rake_world = rho - alpha_s."""
    s = rake_world + delta
    return F * np.sin(s), F * np.cos(s)


def lip_column(top_row, z_tip, i_start, n_x, x_tip, dx, eps=LIP_EPS, n_search=LIP_SEARCH, reach=LIP_REACH):
    """The column of one slice that holds the material ahead of the lip: the first of the
    columns i_start .. i_start + n_search - 1 (inside the pile) whose top lies more than eps
    above the lip and whose near edge (i dx) lies at most dx / 2 + reach ahead of the lip
    (x_tip), or -1. A small roll-back puts the lip behind the centre of a column it
    already cut down to its own height; that column is skipped instead of read as a zero
    depth. Material further ahead is not touched by the lip: no wedge."""
    for i in range(max(i_start, 0), min(i_start + n_search, n_x)):
        if i * dx - x_tip > 0.5 * dx + reach:
            return -1
        if top_row[i] > z_tip + eps:
            return i
    return -1


def surface_fit(top_row, x_centers, i0, depth_v, dx, h, n_x, x_tip):
    """The surface ahead of the lip, one slice: (alpha_s, z_s), the slope angle of the
    least-squares line through the column tops (x_i, top_i), i = i0 .. i0 + n - 1,
    n = clip(ceil(WINDOW_DEPTHS depth_v / dx) + 1, 2, WINDOW_MAX), clipped to +-SLOPE_MAX, and
    that line's height at the lip, x_tip. Columns past the pile's back end (i >= n_x) are the
    plateau held by the draw point's back wall, at height h. Columns behind i0 (cut by the lip)
    are not part of the surface ahead."""
    n = min(max(int(math.ceil(WINDOW_DEPTHS * depth_v / dx)) + 1, 2), WINDOW_MAX)
    sx = sz = sxx = sxz = 0.0
    for k in range(n):
        i = i0 + k
        if i < n_x:
            xi, zi = x_centers[i], top_row[i]
        else:
            xi, zi = (i + 0.5) * dx, h
        sx += xi
        sz += zi
        sxx += xi * xi
        sxz += xi * zi
    m = (n * sxz - sx * sz) / (n * sxx - sx * sx)
    a = min(max(math.atan(m), -SLOPE_MAX), SLOPE_MAX)
    return a, sz / n + math.tan(a) * (x_tip - sx / n)


def lip_depth(top_row, x_centers, z_tip, x_tip, i0, dx, h, n_x):
    """(vertical depth of the lip under the surface ahead, alpha_s): the fitted line's height
    at the lip minus the lip's, limited to [0, top[i0] - z_tip] (the line may not put more
    material above the lip than the lip column holds)."""
    dv0 = top_row[i0] - z_tip
    alpha_s, z_s = surface_fit(top_row, x_centers, i0, dv0, dx, h, n_x, x_tip)
    return min(max(z_s - z_tip, 0.0), dv0), alpha_s


def slice_force(x_tip, z_tip, rake_world, top_row, x_centers, dx, dz, h, n_x, w, q, c_a, rake_lo,
                density_col, cohesion_col, klass_col, phis, deltas, beta_grid=BETA_GRID):
    """FEE of one slice (the reference of the kernel's per-slice arithmetic).

    top_row: the slice's column tops; density_col, cohesion_col, klass_col: its (n_x, n_z)
    voxel arrays. Returns (F_h, F_v, depth_normal, alpha_s, rho_face): F_h >= 0 against the
    motion, F_v positive downward; all 0 when the slice has no material ahead of the lip."""
    i_start = int((x_tip + 0.5 * dx) / dx)
    i0 = lip_column(top_row, z_tip, i_start, n_x, x_tip, dx)
    if i0 < 0:
        return 0.0, 0.0, 0.0, 0.0, 0.0
    dv, alpha_s = lip_depth(top_row, x_centers, z_tip, x_tip, i0, dx, h, n_x)
    if dv <= 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0
    dn = dv * math.cos(alpha_s)
    n_z = density_col.shape[1]
    k = min(max(int((z_tip + 0.5 * dv) / dz), 0), n_z - 1)  # the soil at mid-depth of the layer
    kl = int(klass_col[i0, k])
    phi, delta = float(phis[kl]), float(deltas[kl])
    rho = face_rake(rake_world, alpha_s, delta, phi, rake_lo)
    F, _ = fee_min(np.array([dn]), w, density_col[i0, k], cohesion_col[i0, k], q, c_a, alpha_s, rho, delta, phi,
                   beta_grid=beta_grid)
    fh, fv = tool_force_components(float(F[0]), rho - alpha_s, delta)
    return float(fh), float(fv), dn, alpha_s, rho
