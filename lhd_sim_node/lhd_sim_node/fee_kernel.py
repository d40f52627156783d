"""Compiled (numba) inner loop of the pile: cutting, the face-frame FEE for all slices at once
and the payload with its geometric capacity.

It computes exactly what :mod:`lhd_sim_node.fee` (``slice_force``, ``lip_column``,
``surface_fit``) and :meth:`lhd_loading_ros.task.pile.VoxelPile.cut` compute in numpy
(``test_fee_face`` and ``test_sim_physics`` check the two against each other), without the
Python and numpy call overhead that would otherwise dominate the 50 Hz FEE updates inside
each control period. The equations and frames are documented in ``fee.py``.

Per update and slice: find the lip column (bounded search), fit the surface slope over a
bounded window ahead of it, and minimise the face-frame FEE over the failure-angle grid. The
grid's beta-only terms (cot beta, cot(beta + phi), their product) are tabulated per material
class once per pile (``beta_tables``), so each grid point costs a few multiply-adds and one
division: O(slices x grid) per update, no allocation.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .fee import BETA_LOCK, LIP_EPS, LIP_REACH, LIP_SEARCH, SLOPE_MAX, WINDOW_DEPTHS, WINDOW_MAX

G = 9.81
_EPS = 1e-9

# layout of the `out` vector returned by fee_step
(OUT_REMOVED, OUT_FH, OUT_FV, OUT_MOMENT_X, OUT_RAKE, OUT_ENGAGED, OUT_NEXT_CENTER, OUT_REMOVED_VOL,
 OUT_ALPHA_S) = range(9)
OUT_SIZE = 9


def beta_tables(phis, beta):
    """(n_classes, 3, n_beta): cot(beta), cot(beta + phi_k), their product, per material class."""
    phis = np.asarray(phis, dtype=float)
    tab = np.empty((len(phis), 3, len(beta)))
    for k, phi in enumerate(phis):
        cb = 1.0 / np.tan(beta)
        cbp = 1.0 / np.tan(beta + phi)
        tab[k, 0], tab[k, 1], tab[k, 2] = cb, cbp, cb * cbp
    return tab


@njit(cache=True)
def _mass_below(cum, vmass, j, i, z, dz, n_z):
    if z <= 0.0:
        return 0.0
    k = int(z / dz)
    if k > n_z - 1:
        k = n_z - 1
    return cum[j, i, k] + (z - k * dz) / dz * vmass[j, i, k]


@njit(cache=True)
def _lip_column(top, j, z, i_start, n_x, x, dx):
    """fee.lip_column for slice j."""
    i_lo = i_start if i_start > 0 else 0
    i_hi = i_start + LIP_SEARCH
    if i_hi > n_x:
        i_hi = n_x
    for i in range(i_lo, i_hi):
        if i * dx - x > 0.5 * dx + LIP_REACH:
            return -1
        if top[j, i] > z + LIP_EPS:
            return i
    return -1


@njit(cache=True)
def _lip_depth(top, j, x_centers, z, x, i0, dx, h, n_x):
    """fee.lip_depth (with fee.surface_fit) for slice j: (vertical depth, alpha_s)."""
    dv0 = top[j, i0] - z
    n = int(math.ceil(WINDOW_DEPTHS * dv0 / dx)) + 1
    if n < 2:
        n = 2
    if n > WINDOW_MAX:
        n = WINDOW_MAX
    sx = 0.0
    sz = 0.0
    sxx = 0.0
    sxz = 0.0
    for kk in range(n):
        i = i0 + kk
        if i < n_x:
            xi = x_centers[i]
            zi = top[j, i]
        else:
            xi = (i + 0.5) * dx
            zi = h
        sx += xi
        sz += zi
        sxx += xi * xi
        sxz += xi * zi
    m = (n * sxz - sx * sz) / (n * sxx - sx * sx)
    a = math.atan(m)
    if a < -SLOPE_MAX:
        a = -SLOPE_MAX
    if a > SLOPE_MAX:
        a = SLOPE_MAX
    dv = sz / n + math.tan(a) * (x - sx / n) - z
    if dv < 0.0:
        dv = 0.0
    if dv > dv0:
        dv = dv0
    return dv, a


@njit(cache=True)
def face_fee(dn, alpha_s, rho, delta, gamma, c, q, c_a, w, tab_k):
    """min over beta of the face-frame FEE (fee.fee_min for one slice); tab_k = beta_tables[k]."""
    s = rho + delta
    cs = math.cos(s)
    ss = math.sin(s)
    a0h = 0.5 * w * dn * dn * gamma * G
    a1 = w * c * dn
    a2 = w * q * dn
    a3 = w * c_a * dn
    # numerator K0 + K1 cot(b) + K2 cot(b+phi) + K3 cot(b) cot(b+phi), denominator D; the wedge's
    # top is d (cot(b) + cot(rho)) (McKyes: the soil above the blade belongs to the wedge)
    cr = 1.0 / math.tan(rho)
    ca, sa = math.cos(alpha_s), math.sin(alpha_s)
    k0 = a1 + a3 + (a0h * ca + a2) * cr
    k1 = a0h * ca + a2
    k2 = (a0h * sa - a3) * cr
    k3 = a0h * sa + a1
    best = np.inf
    for b in range(tab_k.shape[1]):
        cbp = tab_k[1, b]
        D = cs + ss * cbp
        if D > _EPS and tab_k[0, b] + cr > _EPS:
            num = k0 + k1 * tab_k[0, b] + k2 * cbp + k3 * tab_k[2, b]
            if num < best * D:  # num / D < best without the division (D > 0)
                best = num / D
    if best == np.inf or best < 0.0:
        return 0.0
    return best


@njit(cache=True)
def fee_step(x, z, pitch, cut_x0, cut_z0, next_center, slices,
             top, cum, vmass, density, cohesion, klass, x_centers, y_centers, dx, dz, L, h, w, q, c_a,
             rake_attack, rake_lo, rake_hi, tabs, phis, deltas, com_y, depth_out, out):
    n_z = cum.shape[2] - 1
    n_x = x_centers.shape[0]
    # ---- cutting: columns whose centre the tip passed lose the material above it
    removed = 0.0
    removed_vol = 0.0
    if x >= next_center and x > cut_x0:
        i_lo = int(math.floor(cut_x0 / dx - 0.5)) + 1
        i_hi = int(math.floor(x / dx - 0.5))
        if i_lo < 0:
            i_lo = 0
        if i_hi > n_x - 1:
            i_hi = n_x - 1
        for i in range(i_lo, i_hi + 1):
            zc = cut_z0 + (z - cut_z0) * (x_centers[i] - cut_x0) / (x - cut_x0)
            if zc < 0.0:
                zc = 0.0
            for jj in range(slices.shape[0]):
                j = slices[jj]
                old = top[j, i]
                if old > zc:
                    removed += _mass_below(cum, vmass, j, i, min(old, h), dz, n_z) - _mass_below(cum, vmass, j, i, zc, dz, n_z)
                    removed_vol += (min(old, h) - zc) * dx * w
                    top[j, i] = zc
        next_center = (math.floor(x / dx - 0.5) + 1.5) * dx
    elif x < cut_x0:
        next_center = (math.floor(x / dx - 0.5) + 1.5) * dx
    # ---- FEE on the material ahead of the lip, per slice in the frame of its local surface
    fh = 0.0
    fv = 0.0
    mom = 0.0
    engaged = 0
    alpha_sum = 0.0
    rake = rake_attack - pitch
    if rake < rake_lo:
        rake = rake_lo
    if rake > rake_hi:
        rake = rake_hi
    for jj in range(depth_out.shape[0]):
        depth_out[jj] = 0.0
    xa = x + 0.5 * dx
    if x >= 0.0 and xa < L:
        i_start = int(xa / dx)
        for jj in range(slices.shape[0]):
            j = slices[jj]
            i0 = _lip_column(top, j, z, i_start, n_x, x, dx)
            if i0 < 0:
                continue
            dv, alpha_s = _lip_depth(top, j, x_centers, z, x, i0, dx, h, n_x)
            if dv <= 0.0:
                continue
            dn = dv * math.cos(alpha_s)
            depth_out[jj] = dn
            k = int((z + 0.5 * dv) / dz)
            if k < 0:
                k = 0
            if k > n_z - 1:
                k = n_z - 1
            kl = klass[j, i0, k]
            delta = deltas[kl]
            rho = rake + alpha_s
            if rho < rake_lo:
                rho = rake_lo
            rho_max = math.pi - delta - phis[kl] - BETA_LOCK
            if rho > rho_max:
                rho = rho_max
            F = face_fee(dn, alpha_s, rho, delta, density[j, i0, k], cohesion[j, i0, k], q, c_a, w, tabs[kl])
            s = rho - alpha_s + delta  # the force's angle in the world frame
            fh += F * math.sin(s)
            fvj = F * math.cos(s)
            fv += fvj
            mom += (y_centers[j] - com_y) * fvj
            alpha_sum += alpha_s
            engaged += 1
    out[OUT_REMOVED] = removed
    out[OUT_REMOVED_VOL] = removed_vol
    out[OUT_FH] = fh
    out[OUT_FV] = fv
    out[OUT_MOMENT_X] = mom
    out[OUT_RAKE] = rake
    out[OUT_ENGAGED] = engaged
    out[OUT_NEXT_CENTER] = next_center
    out[OUT_ALPHA_S] = alpha_sum / engaged if engaged > 0 else 0.0


@njit(cache=True)
def interp_clamped(x, xs, ys):
    """np.interp for sorted xs (clamped at the ends)."""
    n = xs.shape[0]
    if x <= xs[0]:
        return ys[0]
    if x >= xs[n - 1]:
        return ys[n - 1]
    lo = 0
    hi = n - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if xs[mid] <= x:
            lo = mid
        else:
            hi = mid
    t = (x - xs[lo]) / (xs[hi] - xs[lo])
    return ys[lo] + t * (ys[hi] - ys[lo])


@njit(cache=True)
def payload_update(st_v, st_m, add_v, add_m, cap):
    """Add a loaded volume/mass to the bucket's content (v, m) and spill what exceeds the
    capacity cap (m^3), at the content's mean density. Returns (v, m, spilled mass)."""
    v = st_v + add_v
    m = st_m + add_m
    spilled = 0.0
    if v > cap:
        if v > 0.0:
            spilled = m * (v - cap) / v
        m -= spilled
        v = cap if cap > 0.0 else 0.0
    return v, m, spilled


# layout of the per-episode state vector used by fee_update
(ST_CUT_X, ST_CUT_Z, ST_NEXT_CENTER, ST_TIP_PREV_X, ST_W_IDEAL, ST_FH, ST_FZ, ST_RAKE, ST_ENGAGED, ST_V_CUT,
 ST_V_BUCKET, ST_M_BUCKET, ST_SPILLED, ST_ALPHA_S, ST_TIP_PREV_Z, ST_MOBILISED) = range(16)
ST_SIZE = 16


# layout of the parameter vector of fee_update (scalars packed to keep the call cheap)
(P_SID_TIP, P_BID_BUCKET, P_TID_FEE, P_BUCKET_MASS0, P_LOADED_FRACTION, P_FEE_DT, P_FEE_MIN_SPEED, P_DX, P_DZ, P_L,
 P_H, P_W, P_Q, P_CA, P_RAKE_ATTACK, P_RAKE_LO, P_RAKE_HI, P_BY_MOTION, P_WEDGE_TAU) = range(19)
P_SIZE = 19


@njit(cache=True)
def wedge_share(dx_tip, dz_tip, alpha, fee_dt, v_min):
    """Share (0-1) of the lip's passive wedge that the tip's last motion (dx_tip, dz_tip over
    fee_dt) mobilises, before the low-pass of `wedge_mobilisation`. A passive wedge resists the
    part of a motion that pushes into the material ahead of the lip: along the face ahead of it
    (t = (cos alpha, sin alpha), alpha the face's slope) or into the face (the inward normal
    n = (sin alpha, -cos alpha)); the part that leaves the face (-n: breakout, the bucket body's)
    or goes back (-t) pushes nothing. With u the motion's direction:
    share = min(1, max(u.t, 0) + max(u.n, 0)). Pushing along the face or level into a slope: 1
    (35 deg: 0.82 + 0.57); diving straight down into a 30 deg face: cos 30 = 0.87; lifting straight
    up out of it: sin 30 = 0.5; lifting out of level ground, curling the lip up and back, reversing:
    0. A tip at rest (speed below v_min, blended linearly) keeps the whole wedge: a stalled bucket
    is held without creep."""
    sp = math.sqrt(dx_tip * dx_tip + dz_tip * dz_tip) / fee_dt
    if sp <= 0.0:
        return 1.0
    w = sp / v_min
    if w > 1.0:
        w = 1.0
    ca = math.cos(alpha)
    sa = math.sin(alpha)
    inv = 1.0 / (sp * fee_dt)
    c_t = (dx_tip * ca + dz_tip * sa) * inv
    c_n = (dx_tip * sa - dz_tip * ca) * inv
    c = (c_t if c_t > 0.0 else 0.0) + (c_n if c_n > 0.0 else 0.0)
    if c > 1.0:
        c = 1.0
    return 1.0 - w + w * c


@njit(cache=True)
def wedge_mobilisation(prev, dx_tip, dz_tip, alpha, fee_dt, v_min, tau):
    """The wedge's mobilised share after one FEE period: `wedge_share` of the period's motion
    through a first-order low-pass of time constant tau (s) from the previous share `prev`. The
    share is computed from the motion the share itself allows, so without the low-pass a
    partly released wedge lets the tip move, which changes the share at the next update: the
    limit then chattered between periods (1,022 -> 481 -> 837 -> 145 -> 973 N pushing while
    lifting slowly into a 30 deg face). The material also takes time to build or lose its wedge."""
    s = wedge_share(dx_tip, dz_tip, alpha, fee_dt, v_min)
    if tau <= 0.0:
        return s
    return prev + (s - prev) * (fee_dt / (tau + fee_dt))


@njit(cache=True)
def fee_update(site_xpos, site_xmat, xipos, xfrc, tendon_fl, body_mass, st, par, slices, top, cum, vmass, density,
               cohesion, klass, x_centers, y_centers, tabs, phis, deltas, cap_pitch, cap_vol, depth_out, out):
    """One FEE update straight on MuJoCo's arrays: read the tip, cut the pile, set the
    tendon's frictionloss (horizontal resistance) and the bucket's xfrc_applied (vertical
    force and its torque about the CoM), load loaded_fraction of the cut volume and mass into
    the bucket, spill what exceeds its capacity at the current pitch, set the bucket's mass."""
    sid_tip = int(par[P_SID_TIP])
    bid_bucket = int(par[P_BID_BUCKET])
    tid_fee = int(par[P_TID_FEE])
    bucket_mass0, loaded_fraction = par[P_BUCKET_MASS0], par[P_LOADED_FRACTION]
    fee_dt, fee_min_speed = par[P_FEE_DT], par[P_FEE_MIN_SPEED]
    dx, dz, L, h, w, q, c_a = par[P_DX], par[P_DZ], par[P_L], par[P_H], par[P_W], par[P_Q], par[P_CA]
    rake_attack, rake_lo, rake_hi = par[P_RAKE_ATTACK], par[P_RAKE_LO], par[P_RAKE_HI]
    x = site_xpos[sid_tip, 0]
    z = site_xpos[sid_tip, 2]
    pitch = math.atan2(site_xmat[sid_tip, 6], site_xmat[sid_tip, 0])
    fee_step(x, z, pitch, st[ST_CUT_X], st[ST_CUT_Z], st[ST_NEXT_CENTER], slices, top, cum, vmass, density, cohesion,
             klass, x_centers, y_centers, dx, dz, L, h, w, q, c_a, rake_attack, rake_lo, rake_hi, tabs, phis, deltas,
             xipos[bid_bucket, 1], depth_out, out)
    st[ST_NEXT_CENTER] = out[OUT_NEXT_CENTER]
    # ---- payload: loaded_fraction of the cut, limited by the bucket's geometry at this pitch
    add_v = 0.0
    add_m = 0.0
    if out[OUT_REMOVED_VOL] > 0.0:
        st[ST_W_IDEAL] += out[OUT_REMOVED]
        st[ST_V_CUT] += out[OUT_REMOVED_VOL]
        add_v = loaded_fraction * out[OUT_REMOVED_VOL]
        add_m = loaded_fraction * out[OUT_REMOVED]
    if add_v > 0.0 or st[ST_V_BUCKET] > 0.0:
        cap = interp_clamped(pitch, cap_pitch, cap_vol)
        v, m, spilled = payload_update(st[ST_V_BUCKET], st[ST_M_BUCKET], add_v, add_m, cap)
        if add_v > 0.0 or spilled > 0.0:
            st[ST_V_BUCKET] = v
            st[ST_M_BUCKET] = m
            st[ST_SPILLED] += spilled
            body_mass[bid_bucket] = bucket_mass0 + m
    st[ST_CUT_X] = x
    st[ST_CUT_Z] = z
    dx_tip = x - st[ST_TIP_PREV_X]
    dz_tip = z - st[ST_TIP_PREV_Z]
    v_tip = dx_tip / fee_dt
    st[ST_TIP_PREV_X] = x
    st[ST_TIP_PREV_Z] = z
    st[ST_RAKE] = out[OUT_RAKE]
    st[ST_ENGAGED] = out[OUT_ENGAGED]
    st[ST_ALPHA_S] = out[OUT_ALPHA_S]
    if out[OUT_ENGAGED] == 0.0:
        st[ST_MOBILISED] = 1.0      # the next contact starts with the whole wedge
        tendon_fl[tid_fee] = 0.0
        for c in range(6):
            xfrc[bid_bucket, c] = 0.0
        st[ST_FH] = 0.0
        st[ST_FZ] = 0.0
        return
    mob = 1.0
    if par[P_BY_MOTION] != 0.0:
        mob = wedge_mobilisation(st[ST_MOBILISED], dx_tip, dz_tip, out[OUT_ALPHA_S], fee_dt, fee_min_speed,
                                 par[P_WEDGE_TAU])
    st[ST_MOBILISED] = mob
    tendon_fl[tid_fee] = mob * out[OUT_FH]
    ramp = v_tip / fee_min_speed
    if ramp < 0.0:
        ramp = 0.0
    if ramp > 1.0:
        ramp = 1.0
    fz = -ramp * out[OUT_FV]
    xfrc[bid_bucket, 0] = 0.0
    xfrc[bid_bucket, 1] = 0.0
    xfrc[bid_bucket, 2] = fz
    xfrc[bid_bucket, 3] = -ramp * out[OUT_MOMENT_X]
    xfrc[bid_bucket, 4] = -(x - xipos[bid_bucket, 0]) * fz
    xfrc[bid_bucket, 5] = 0.0
    st[ST_FH] = mob * out[OUT_FH]
    st[ST_FZ] = fz
