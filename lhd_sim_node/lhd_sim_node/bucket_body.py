"""The whole bucket in the pile: breakout of the material over the opening and ploughing of the
bottom (issue 13, item 2). ``docs/modeling.md`` ("The whole bucket") explains the model.

The lip's FEE (``fee_kernel``) resists the lip only. This module adds, once per FEE update:

(a) **Breakout** of the block of material over the bucket's opening: the columns of the pile
    whose centres lie over the bottom plate (within the bucket's width), from the plate's top
    surface up to the material surface. When the bucket curls or lifts, the block must be
    lifted and sheared free (Meyerhof & Adams 1968, vertical slip planes):

        F_lift = W_ob + S_sides + S_front + S_back
        S      = integral over a vertical plane of tau,  tau = c + K_u sigma_v tan(phi)
                 (soil on soil), or c_a + K_u sigma_v tan(delta) (soil on the side/back walls),
                 sigma_v = gamma g (depth below the material surface)
        W_ob   = g max(0, M_over - payload): the material over the plate that is not already
                 the payload (whose weight MuJoCo carries as bucket mass)
        T_curl = sum over side strips of S_strip r_strip (distance from the bucket joint)
                 + W_ob (x_centroid - x_joint) + S_front (x_lip - x_joint)

(b) **Ploughing** of the bottom plate and heel below the pile surface, moving forward: Rankine's
    passive pressure on the depth h by which the plate's top surface lies below the material
    surface (the lip cuts at that surface; a curled bucket's heel lies below the lip's cut):

        P_plough = sum_j dy (1/2 gamma g h_j^2 K_p + 2 c h_j sqrt(K_p)),  K_p = (1 + sin phi)/(1 - sin phi)

The material surface over the plate is the surface *before the lip cut it* (``ob``): the
voxel pile removes the columns the tip passes, but physically that material is still over the
bucket until the bucket leaves the column. ``ob`` is kept per column and falls back to the
pile's top as soon as the column is no longer over the plate.

All three resist as dry friction, set every FEE update: ``F_lift`` on a vertical tendon from a
far anchor above to the bucket (``body_z``), ``T_curl`` as the bucket joint's
``dof_frictionloss``, ``P_plough`` on a horizontal tendon from the far FEE anchor behind to the
heel (``body_x``). MuJoCo's dry friction stops the motion up to the limit and never pushes.
The vertical tendon ends at the bucket joint, so curling does not stretch it (T_curl alone
resists the curl); the heel's tendon also resists the heel's forward swing when the bucket curls,
which is the plough's share of the curl resistance.

``bucket_body_update`` is the compiled kernel the simulator calls; ``body_forces_reference``
is a numpy reference of the same model that ``test_bucket_body`` checks the kernel against.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from lhd_loading_ros.task.kinematics import PLATE_T, arm_offsets

G = 9.81

# parameter vector of bucket_body_update
(P_BID, P_DOF, P_TID_Z, P_TID_X, P_MASS0, P_LB, P_TOPZ, P_WALL_H, P_BACK_H, P_K_UP, P_DX, P_DY, P_DZ, P_CA,
 P_ENABLED) = range(15)
P_SIZE = 15

# output vector (diagnostics; the first three are what is applied)
(O_LIFT, O_CURL, O_PLOUGH, O_W_OB, O_M_OVER, O_S_SIDE, O_S_FRONT, O_S_BACK, O_H_FRONT, O_H_PLOUGH, O_T_SIDE,
 O_T_WEIGHT, O_T_FRONT) = range(13)
O_SIZE = 13
O_NAMES = ("lift", "curl", "plough", "w_ob", "m_over", "s_side", "s_front", "s_back", "h_front", "h_plough",
           "t_side", "t_weight", "t_front")


def bucket_geometry(mc: dict) -> dict:
    """Bucket-frame geometry (origin at the bucket joint, x towards the lip, z up in the attack
    pose), as the MJCF builds the bucket: plate length, plate top height, side-wall and back-wall
    heights above the plate's top."""
    o = arm_offsets(mc)
    return {"lb": mc["bucket_tip_ahead_of_hinge"], "top_z": o["top_z"], "wall_h": mc["bucket_back_height"] / 2,
            "back_h": mc["bucket_back_height"], "plate_t": PLATE_T}


def make_params(cfg: dict, bid: int, dof: int, tid_z: int, tid_x: int, mass0: float, pile) -> np.ndarray:
    g = bucket_geometry(cfg["machine"])
    bb = cfg["bucket_body"]
    par = np.zeros(P_SIZE)
    par[[P_BID, P_DOF, P_TID_Z, P_TID_X, P_MASS0]] = bid, dof, tid_z, tid_x, mass0
    par[[P_LB, P_TOPZ, P_WALL_H, P_BACK_H]] = g["lb"], g["top_z"], g["wall_h"], g["back_h"]
    par[[P_K_UP, P_DX, P_DY, P_DZ, P_CA]] = bb["k_uplift"], pile.dx, pile.dy, pile.dz, pile.adhesion
    par[P_ENABLED] = bb["enabled"]
    return par


# ---------------------------------------------------------------------------------------- kernel
@njit(cache=True)
def _mass_between(cum, vmass, j, i, z0, z1, dz, n_z):
    """Mass of column (j, i) between heights z0 < z1."""
    m = 0.0
    for s in range(2):
        z = z0 if s == 0 else z1
        if z <= 0.0:
            mb = 0.0
        else:
            k = int(z / dz)
            if k > n_z - 1:
                k = n_z - 1
            mb = cum[j, i, k] + (z - k * dz) / dz * vmass[j, i, k]
        m = mb - m if s == 1 else mb
    return m if m > 0.0 else 0.0


@njit(cache=True)
def _plane_shear(H, d1, c, c_a, kg, tan_phi, tan_delta):
    """Shear per unit length of a vertical plane from the material surface down to depth H:
    soil on soil down to depth d1 (c + kg d tan phi), soil on steel below it (c_a + kg d tan delta),
    kg = K gamma g. Exact integral of the linear stresses."""
    if d1 > H:
        d1 = H
    if d1 < 0.0:
        d1 = 0.0
    return c * d1 + 0.5 * kg * tan_phi * d1 * d1 + c_a * (H - d1) + 0.5 * kg * tan_delta * (H * H - d1 * d1)


@njit(cache=True)
def _k(z, dz, n_z):
    k = int(z / dz)
    if k < 0:
        k = 0
    if k > n_z - 1:
        k = n_z - 1
    return k


@njit(cache=True)
def body_forces(hx, hz, r00, r02, r20, r22, payload, par, slices, top, ob, cum, vmass, density, cohesion, phi, delta,
                x_centers, out):
    """Breakout and ploughing for the bucket joint at (hx, hz) with the bucket's rotation
    (r00 r02; r20 r22) in the xz-plane; writes ``out`` (O_*)."""
    for c in range(O_SIZE):
        out[c] = 0.0
    lb, top_z, wall_h, back_h = par[P_LB], par[P_TOPZ], par[P_WALL_H], par[P_BACK_H]
    k_up, dx, dy, dz, c_a = par[P_K_UP], par[P_DX], par[P_DY], par[P_DZ], par[P_CA]
    n_x = x_centers.shape[0]
    n_z = cum.shape[2] - 1
    if r00 < 0.05:  # plate nearly vertical or past it: no opening over the plate
        return
    # plate top line: heel (s = 0) to lip (s = lb)
    ex = hx + top_z * r02
    ez = hz + top_z * r22
    tx = ex + lb * r00
    tz = ez + lb * r20
    slope = r20 / r00
    wall_dz = wall_h * (r22 - r02 * r20 / r00)  # vertical offset of the side walls' top edge
    j_lo = slices[0]
    j_hi = slices[slices.shape[0] - 1]
    m_over = 0.0
    mx = 0.0
    s_side = 0.0
    t_side = 0.0
    h_pl_sum = 0.0
    plough = 0.0
    i0 = int(math.floor(ex / dx - 0.5)) + 1
    if i0 < 0:
        i0 = 0
    for jj in range(slices.shape[0]):
        j = slices[jj]
        h_pl = 0.0
        i = i0
        while i < n_x and x_centers[i] <= tx:
            xi = x_centers[i]
            zf = ez + (xi - ex) * slope
            # (b) ploughing: the plate below the current surface (not the lip's own column)
            if xi < tx - dx:
                p = top[j, i] - zf
                if p > h_pl:
                    h_pl = p
            # (a) the block over the plate
            s = ob[j, i]
            H = s - zf
            if H > 0.0:
                m = _mass_between(cum, vmass, j, i, zf if zf > 0.0 else 0.0, s, dz, n_z)
                m_over += m
                mx += m * xi
                if j == j_lo or j == j_hi:
                    k = _k(0.5 * (zf + s), dz, n_z)
                    kg = k_up * density[j, i, k] * G
                    d1 = s - (zf + wall_dz)
                    S = dx * _plane_shear(H, d1, cohesion[j, i, k], c_a, kg, math.tan(phi[j, i, k]),
                                          math.tan(delta[j, i, k]))
                    n_sides = 2.0 if j_lo == j_hi else 1.0
                    s_side += n_sides * S
                    t_side += n_sides * S * math.hypot(xi - hx, 0.5 * (zf + s) - hz)
            i += 1
        if h_pl > 0.0:  # soil of the column under the plate's middle, at mid-depth of the ploughed layer
            ic = min(max(int((ex + 0.5 * lb * r00) / dx), 0), n_x - 1)
            k = _k(top[j, ic] - 0.5 * h_pl, dz, n_z)
            sp = math.sin(phi[j, ic, k])
            kp = (1.0 + sp) / (1.0 - sp)
            plough += dy * (0.5 * density[j, ic, k] * G * h_pl * h_pl * kp
                            + 2.0 * cohesion[j, ic, k] * h_pl * math.sqrt(kp))
            h_pl_sum += h_pl
    # front plane: vertical through the lip, up to the material surface just ahead of the lip: the
    # higher of the lip's own column and the next (a lip that rolled back a few mm behind the centre
    # of a column it cut still has the next column's material over it)
    s_front = 0.0
    h_front = 0.0
    ia = int(tx / dx)
    if tx >= 0.0 and ia < n_x:
        ia2 = ia + 1 if ia + 1 < n_x else ia
        for jj in range(slices.shape[0]):
            j = slices[jj]
            i = ia2 if top[j, ia2] > top[j, ia] else ia
            Hf = top[j, i] - tz
            if Hf > 0.0:
                k = _k(tz + 0.5 * Hf, dz, n_z)
                kg = k_up * density[j, i, k] * G
                s_front += dy * _plane_shear(Hf, Hf, cohesion[j, i, k], c_a, kg, math.tan(phi[j, i, k]), 0.0)
                h_front += Hf / slices.shape[0]
    # back plane: vertical through the back wall, up to the surface of the column behind the heel
    s_back = 0.0
    ib = int(math.floor((ex - 0.5 * dx) / dx))
    if ib >= 0 and ib < n_x:
        back_dz = back_h * r22  # the back wall's top edge above the heel
        for jj in range(slices.shape[0]):
            j = slices[jj]
            Hb = top[j, ib] - ez
            if Hb > 0.0:
                k = _k(ez + 0.5 * Hb, dz, n_z)
                kg = k_up * density[j, ib, k] * G
                s_back += dy * _plane_shear(Hb, top[j, ib] - (ez + back_dz), cohesion[j, ib, k], c_a, kg,
                                            math.tan(phi[j, ib, k]), math.tan(delta[j, ib, k]))
    w_ob = G * (m_over - payload) if m_over > payload else 0.0
    xbar = mx / m_over if m_over > 0.0 else hx
    t_weight = w_ob * (xbar - hx) if xbar > hx else 0.0
    t_front = s_front * (tx - hx) if tx > hx else 0.0
    out[O_LIFT] = w_ob + s_side + s_front + s_back
    out[O_CURL] = t_side + t_weight + t_front
    out[O_PLOUGH] = plough
    out[O_W_OB] = w_ob
    out[O_M_OVER] = m_over
    out[O_S_SIDE] = s_side
    out[O_S_FRONT] = s_front
    out[O_S_BACK] = s_back
    out[O_H_FRONT] = h_front
    out[O_H_PLOUGH] = h_pl_sum / slices.shape[0]
    out[O_T_SIDE] = t_side
    out[O_T_WEIGHT] = t_weight
    out[O_T_FRONT] = t_front


@njit(cache=True)
def update_overburden(ex, tx, top, ob, x_centers):
    """ob: the material surface over each column. A column over the plate keeps the surface it
    had before the lip cut it; every other column takes the pile's top."""
    for i in range(x_centers.shape[0]):
        under = ex <= x_centers[i] <= tx
        if not under:
            for j in range(top.shape[0]):
                ob[j, i] = top[j, i]


@njit(cache=True)
def bucket_body_update(xpos, xmat, body_mass, dof_fl, tendon_fl, par, slices, top, ob, cum, vmass, density, cohesion,
                       phi, delta, x_centers, out):
    """One update straight on MuJoCo's arrays: bucket pose -> breakout and plough limits ->
    dof_frictionloss of the bucket joint and frictionloss of the body_z / body_x tendons."""
    bid = int(par[P_BID])
    dof = int(par[P_DOF])
    tz_id = int(par[P_TID_Z])
    tx_id = int(par[P_TID_X])
    hx = xpos[bid, 0]
    hz = xpos[bid, 2]
    r00, r02, r20, r22 = xmat[bid, 0], xmat[bid, 2], xmat[bid, 6], xmat[bid, 8]
    ex = hx + par[P_TOPZ] * r02
    tx = ex + par[P_LB] * r00
    update_overburden(min(ex, tx), max(ex, tx), top, ob, x_centers)
    if par[P_ENABLED] == 0.0 or slices.shape[0] == 0:
        for c in range(O_SIZE):
            out[c] = 0.0
    else:
        payload = body_mass[bid] - par[P_MASS0]
        body_forces(hx, hz, r00, r02, r20, r22, payload if payload > 0.0 else 0.0, par, slices, top, ob, cum, vmass,
                    density, cohesion, phi, delta, x_centers, out)
    dof_fl[dof] = out[O_CURL]
    tendon_fl[tz_id] = out[O_LIFT]
    tendon_fl[tx_id] = out[O_PLOUGH]


# ------------------------------------------------------------------------------- numpy reference
def body_forces_reference(hinge_xz, rot_xz, payload: float, par: np.ndarray, slices: np.ndarray, pile,
                          ob: np.ndarray) -> dict:
    """The same model vectorised in numpy (test reference for the kernel). rot_xz = ((r00, r02),
    (r20, r22)). Returns a dict keyed by O_NAMES."""
    out = dict.fromkeys(O_NAMES, 0.0)
    hx, hz = hinge_xz
    (r00, r02), (r20, r22) = rot_xz
    lb, top_z, wall_h, back_h = par[P_LB], par[P_TOPZ], par[P_WALL_H], par[P_BACK_H]
    k_up, c_a = par[P_K_UP], par[P_CA]
    dx, dy, dz, nz = pile.dx, pile.dy, pile.dz, pile.n_z
    if r00 < 0.05:
        return out
    ex, ez = hx + top_z * r02, hz + top_z * r22
    tx, tz = ex + lb * r00, ez + lb * r20
    xc = pile.x_centers
    cols = np.nonzero((xc >= ex) & (xc <= tx))[0]
    zf = ez + (xc[cols] - ex) * r20 / r00
    J = slices[:, None]
    I = cols[None, :]
    H = ob[J, I] - zf[None, :]
    lo = np.maximum(zf, 0.0)[None, :] * np.ones_like(H)
    hi = ob[J, I]
    m = np.where(H > 0.0, pile.mass_below(J * np.ones_like(I), I * np.ones_like(J), hi)
                 - pile.mass_below(J * np.ones_like(I), I * np.ones_like(J), lo), 0.0)
    m = np.maximum(m, 0.0)
    m_over = float(m.sum())
    xbar = float((m * xc[cols][None, :]).sum() / m_over) if m_over > 0 else hx

    def kidx(z):
        return np.clip((np.asarray(z) / dz).astype(int), 0, nz - 1)

    def shear(Hs, d1, c, kg, tp, td):
        d1 = np.clip(d1, 0.0, Hs)
        return c * d1 + 0.5 * kg * tp * d1 ** 2 + c_a * (Hs - d1) + 0.5 * kg * td * (Hs ** 2 - d1 ** 2)

    s_side = t_side = 0.0
    edges = sorted({int(slices[0]), int(slices[-1])})
    n_sides = 2.0 if len(edges) == 1 else 1.0
    wall_dz = wall_h * (r22 - r02 * r20 / r00)
    for j in edges:
        s = ob[j, cols]
        Hs = s - zf
        ok = Hs > 0.0
        zm = 0.5 * (zf + s)
        k = kidx(zm)
        kg = k_up * pile.density[j, cols, k] * G
        S = dx * shear(Hs, s - (zf + wall_dz), pile.cohesion[j, cols, k], kg, np.tan(pile.phi[j, cols, k]),
                       np.tan(pile.delta[j, cols, k]))
        S = np.where(ok, S, 0.0) * n_sides
        s_side += float(S.sum())
        t_side += float((S * np.hypot(xc[cols] - hx, zm - hz)).sum())
    # plough
    plough = 0.0
    pc = cols[xc[cols] < tx - dx]
    h_sum = 0.0
    if len(pc):
        ic = min(max(int((ex + 0.5 * lb * r00) / dx), 0), pile.n_x - 1)
        zfp = ez + (xc[pc] - ex) * r20 / r00
        for j in slices:
            h = max(float(np.max(pile.top[j, pc] - zfp)), 0.0)
            if h > 0.0:
                k = int(kidx(pile.top[j, ic] - 0.5 * h))
                sp = math.sin(pile.phi[j, ic, k])
                kp = (1 + sp) / (1 - sp)
                plough += dy * (0.5 * pile.density[j, ic, k] * G * h * h * kp
                                + 2 * pile.cohesion[j, ic, k] * h * math.sqrt(kp))
                h_sum += h
    # front
    s_front = h_front = 0.0
    i0 = int(tx / dx)
    if tx >= 0.0 and i0 < pile.n_x:
        i1 = min(i0 + 1, pile.n_x - 1)
        for j in slices:
            ia = i1 if pile.top[j, i1] > pile.top[j, i0] else i0
            hf = pile.top[j, ia] - tz
            if hf > 0.0:
                k = int(kidx(tz + 0.5 * hf))
                kg = k_up * pile.density[j, ia, k] * G
                s_front += dy * float(shear(hf, hf, pile.cohesion[j, ia, k], kg, math.tan(pile.phi[j, ia, k]), 0.0))
                h_front += hf / len(slices)
    # back
    s_back = 0.0
    ib = int(math.floor((ex - 0.5 * dx) / dx))
    if 0 <= ib < pile.n_x:
        for j in slices:
            hb = pile.top[j, ib] - ez
            if hb > 0.0:
                k = int(kidx(ez + 0.5 * hb))
                kg = k_up * pile.density[j, ib, k] * G
                s_back += dy * float(shear(hb, pile.top[j, ib] - (ez + back_h * r22), pile.cohesion[j, ib, k], kg,
                                           math.tan(pile.phi[j, ib, k]), math.tan(pile.delta[j, ib, k])))
    w_ob = G * max(m_over - payload, 0.0)
    t_weight = w_ob * max(xbar - hx, 0.0)
    t_front = s_front * max(tx - hx, 0.0)
    out.update(lift=w_ob + s_side + s_front + s_back, curl=t_side + t_weight + t_front, plough=plough,
               w_ob=w_ob, m_over=m_over, s_side=s_side, s_front=s_front, s_back=s_back, h_front=h_front,
               h_plough=h_sum / len(slices), t_side=t_side, t_weight=t_weight, t_front=t_front)
    return out


class BucketBody:
    """Binds the kernel to one simulator episode (views into MuJoCo's and the pile's arrays)."""

    def __init__(self, cfg: dict, model):
        self.cfg = cfg
        self.enabled = bool(cfg["bucket_body"]["enabled"])
        self.bid = model.body("bucket").id
        self.dof = int(model.jnt_dofadr[model.joint("bucket").id])
        self.tid_z = model.tendon("body_z").id
        self.tid_x = model.tendon("body_x").id
        self.out = np.zeros(O_SIZE)
        self.args = None

    def bind(self, model, data, pile, slices: np.ndarray, mass0: float) -> tuple:
        model.dof_frictionloss[self.dof] = 0.0
        model.tendon_frictionloss[self.tid_z] = 0.0
        model.tendon_frictionloss[self.tid_x] = 0.0
        self.ob = pile.top.copy()
        self.par = make_params(self.cfg, self.bid, self.dof, self.tid_z, self.tid_x, mass0, pile)
        self.par[P_ENABLED] = float(self.enabled)
        self.pile = pile
        self.slices = np.ascontiguousarray(slices, dtype=np.int64)
        self.out[:] = 0.0
        self.args = (data.xpos, data.xmat, model.body_mass, model.dof_frictionloss, model.tendon_frictionloss,
                     self.par, self.slices, pile.top, self.ob, pile._cum, pile._voxel_mass, pile.density,
                     pile.cohesion, pile.phi, pile.delta, pile.x_centers, self.out)
        return self.args

    def report(self) -> dict:
        """The last update's limits and their parts (N, N m, kg, m)."""
        return {n: float(v) for n, v in zip(O_NAMES, self.out)}
