"""Compiled (numba) inner loop of the pile: cutting and the FEE for all slices at once.

It computes exactly what :class:`lhd_sim_node.fee.FeeTable` and
:meth:`lhd_loading_ros.task.pile.VoxelPile.cut` compute in numpy (``test_fee_kernel`` checks
the two against each other), without the Python and numpy call overhead that would
otherwise dominate the 50 Hz FEE updates inside each control period.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

G = 9.81
_BIG = 1e12
_EPS = 1e-9

# layout of the `out` vector returned by fee_step
OUT_REMOVED, OUT_FH, OUT_FV, OUT_MOMENT_X, OUT_RAKE, OUT_ENGAGED, OUT_NEXT_CENTER = range(7)
OUT_SIZE = 7


@njit(cache=True)
def _n_grid(beta, alpha, rake, delta, phi, out):
    """N_gamma, N_c, N_q, N_a over the failure-angle grid into out[4, n]; inadmissible
    wedges get _BIG; if no wedge is admissible the grid is zero (no resistance)."""
    tan_a = math.tan(alpha)
    s = rake + delta
    cs, ss = math.cos(s), math.sin(s)
    cot_r = 1.0 / math.tan(rake)
    any_valid = False
    for b in range(beta.shape[0]):
        cot_bp = 1.0 / math.tan(beta[b] + phi)
        cot_b = 1.0 / math.tan(beta[b])
        D = cs + ss * cot_bp
        if D > _EPS and cot_b > tan_a + _EPS:
            slope_term = math.cos(alpha) + math.sin(alpha) * cot_bp
            geo = (cot_b - tan_a) * slope_term / D
            out[0, b] = 0.5 * geo
            out[1, b] = (1.0 + cot_b * cot_bp) / D
            out[2, b] = geo
            out[3, b] = (1.0 - cot_r * cot_bp) / D
            any_valid = True
        else:
            out[0, b] = _BIG
            out[1, b] = _BIG
            out[2, b] = _BIG
            out[3, b] = _BIG
    if not any_valid:
        out[:, :] = 0.0


@njit(cache=True)
def _mass_below(cum, vmass, j, i, z, dz, n_z):
    if z <= 0.0:
        return 0.0
    k = int(z / dz)
    if k > n_z - 1:
        k = n_z - 1
    return cum[j, i, k] + (z - k * dz) / dz * vmass[j, i, k]


@njit(cache=True)
def fee_step(x, z, pitch, cut_x0, cut_z0, next_center, slices,
             top, cum, vmass, density, cohesion, klass, x_centers, y_centers, dx, dz, L, h, w, q, c_a,
             alpha, rake_attack, rake_lo, rake_hi, rake_step, grids, filled, phis, deltas, beta, com_y,
             depth_out, out):
    n_z = cum.shape[2] - 1
    # ---- cutting: columns whose centre the tip passed lose the material above it
    removed = 0.0
    if x >= next_center and x > cut_x0:
        i_lo = int(math.floor(cut_x0 / dx - 0.5)) + 1
        i_hi = int(math.floor(x / dx - 0.5))
        if i_lo < 0:
            i_lo = 0
        if i_hi > x_centers.shape[0] - 1:
            i_hi = x_centers.shape[0] - 1
        for i in range(i_lo, i_hi + 1):
            zc = cut_z0 + (z - cut_z0) * (x_centers[i] - cut_x0) / (x - cut_x0)
            if zc < 0.0:
                zc = 0.0
            for jj in range(slices.shape[0]):
                j = slices[jj]
                old = top[j, i]
                if old > zc:
                    removed += _mass_below(cum, vmass, j, i, min(old, h), dz, n_z) - _mass_below(cum, vmass, j, i, zc, dz, n_z)
                    top[j, i] = zc
        next_center = (math.floor(x / dx - 0.5) + 1.5) * dx
    elif x < cut_x0:
        next_center = (math.floor(x / dx - 0.5) + 1.5) * dx
    # ---- FEE on the material ahead of the tip
    fh = 0.0
    fv = 0.0
    mom = 0.0
    engaged = 0
    rake = rake_attack - pitch
    if rake < rake_lo:
        rake = rake_lo
    if rake > rake_hi:
        rake = rake_hi
    for jj in range(depth_out.shape[0]):
        depth_out[jj] = 0.0
    xa = x + 0.5 * dx
    if x >= 0.0 and xa < L:
        i = int(xa / dx)
        ri = int(round((rake - rake_lo) / rake_step))
        rk = rake_lo + ri * rake_step
        for jj in range(slices.shape[0]):
            j = slices[jj]
            depth = top[j, i] - z
            if depth <= 0.0:
                continue
            depth_out[jj] = depth
            k = int((z + 0.5 * depth) / dz)
            if k < 0:
                k = 0
            if k > n_z - 1:
                k = n_z - 1
            kl = klass[j, i, k]
            if not filled[kl, ri]:
                _n_grid(beta, alpha, rk, deltas[kl], phis[kl], grids[kl, ri])
                filled[kl, ri] = True
            N = grids[kl, ri]
            a0 = w * depth * depth * density[j, i, k] * G
            a1 = w * cohesion[j, i, k] * depth
            a2 = w * q * depth
            a3 = w * c_a * depth
            F = _BIG * 10.0
            for b in range(N.shape[1]):
                f = a0 * N[0, b] + a1 * N[1, b] + a2 * N[2, b] + a3 * N[3, b]
                if f < F:
                    F = f
            if F < 0.0:
                F = 0.0
            s = rk + deltas[kl]
            fh += F * math.sin(s)
            fvj = F * math.cos(s)
            fv += fvj
            mom += (y_centers[j] - com_y) * fvj
            engaged += 1
    out[OUT_REMOVED] = removed
    out[OUT_FH] = fh
    out[OUT_FV] = fv
    out[OUT_MOMENT_X] = mom
    out[OUT_RAKE] = rake
    out[OUT_ENGAGED] = engaged
    out[OUT_NEXT_CENTER] = next_center


def make_grids(n_classes: int, rake_lo: float, rake_hi: float, rake_step: float, n_beta: int):
    n_rake = int(round((rake_hi - rake_lo) / rake_step)) + 1
    return np.zeros((n_classes, n_rake, 4, n_beta)), np.zeros((n_classes, n_rake), dtype=np.bool_)


# layout of the per-episode state vector used by fee_update
ST_CUT_X, ST_CUT_Z, ST_NEXT_CENTER, ST_TIP_PREV_X, ST_W_IDEAL, ST_FH, ST_FZ, ST_RAKE, ST_ENGAGED = range(9)
ST_SIZE = 9


# layout of the parameter vector of fee_update (scalars packed to keep the call cheap)
(P_SID_TIP, P_BID_BUCKET, P_TID_FEE, P_BUCKET_MASS0, P_LOADED_FRACTION, P_FEE_DT, P_FEE_MIN_SPEED, P_DX, P_DZ, P_L,
 P_H, P_W, P_Q, P_CA, P_ALPHA, P_RAKE_ATTACK, P_RAKE_LO, P_RAKE_HI, P_RAKE_STEP, P_MAX_LOAD) = range(20)
P_SIZE = 20


@njit(cache=True)
def fee_update(site_xpos, site_xmat, xipos, xfrc, tendon_fl, body_mass, st, par, slices, top, cum, vmass, density,
               cohesion, klass, x_centers, y_centers, grids, filled, phis, deltas, beta, depth_out, out):
    """One FEE update straight on MuJoCo's arrays: read the tip, cut the pile, set the
    tendon's frictionloss (horizontal resistance) and the bucket's xfrc_applied (vertical
    force and its torque about the CoM), add the payload to the bucket's mass."""
    sid_tip = int(par[P_SID_TIP])
    bid_bucket = int(par[P_BID_BUCKET])
    tid_fee = int(par[P_TID_FEE])
    bucket_mass0, loaded_fraction = par[P_BUCKET_MASS0], par[P_LOADED_FRACTION]
    fee_dt, fee_min_speed = par[P_FEE_DT], par[P_FEE_MIN_SPEED]
    dx, dz, L, h, w, q, c_a = par[P_DX], par[P_DZ], par[P_L], par[P_H], par[P_W], par[P_Q], par[P_CA]
    alpha, rake_attack, rake_lo = par[P_ALPHA], par[P_RAKE_ATTACK], par[P_RAKE_LO]
    rake_hi, rake_step = par[P_RAKE_HI], par[P_RAKE_STEP]
    x = site_xpos[sid_tip, 0]
    z = site_xpos[sid_tip, 2]
    pitch = math.atan2(site_xmat[sid_tip, 6], site_xmat[sid_tip, 0])
    fee_step(x, z, pitch, st[ST_CUT_X], st[ST_CUT_Z], st[ST_NEXT_CENTER], slices, top, cum, vmass, density, cohesion,
             klass, x_centers, y_centers, dx, dz, L, h, w, q, c_a, alpha, rake_attack, rake_lo, rake_hi, rake_step,
             grids, filled, phis, deltas, beta, xipos[bid_bucket, 1], depth_out, out)
    st[ST_NEXT_CENTER] = out[OUT_NEXT_CENTER]
    if out[OUT_REMOVED] > 0.0:
        st[ST_W_IDEAL] += out[OUT_REMOVED]
        body_mass[bid_bucket] = bucket_mass0 + min(loaded_fraction * st[ST_W_IDEAL], par[P_MAX_LOAD])
    st[ST_CUT_X] = x
    st[ST_CUT_Z] = z
    v_tip = (x - st[ST_TIP_PREV_X]) / fee_dt
    st[ST_TIP_PREV_X] = x
    st[ST_RAKE] = out[OUT_RAKE]
    st[ST_ENGAGED] = out[OUT_ENGAGED]
    if out[OUT_ENGAGED] == 0.0:
        tendon_fl[tid_fee] = 0.0
        for c in range(6):
            xfrc[bid_bucket, c] = 0.0
        st[ST_FH] = 0.0
        st[ST_FZ] = 0.0
        return
    tendon_fl[tid_fee] = out[OUT_FH]
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
    st[ST_FH] = out[OUT_FH]
    st[ST_FZ] = fz
