"""MuJoCo simulation of the scaled LHD loading a voxelized muck pile.

The pile acts on the bucket only through the extended FEE (no contact physics), applied
through ``xfrc_applied`` as a force plus the torque about the bucket's centre of mass.
The FEE is re-evaluated every ``sim.fee_every`` physics steps inside each 0.1 s control
period. The bucket tip cuts the pile as it moves: the columns it passes lose the material
above the tip; ``loaded_fraction`` (2/3) of the cut mass is the payload, which is added to
the bucket body's mass.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from lhd_loading_ros.task.params import TaskParams
from lhd_loading_ros.task.pile import SoilRanges, VoxelPile
from lhd_loading_ros.task.state import LhdState
from lhd_loading_ros.task.zones import Zones

from .fee import BETA_GRID, FeeTable
from .fee_kernel import (OUT_SIZE, P_ALPHA, P_BID_BUCKET, P_BUCKET_MASS0, P_CA, P_DX, P_DZ, P_FEE_DT,
                         P_FEE_MIN_SPEED, P_H, P_L, P_LOADED_FRACTION, P_Q, P_RAKE_ATTACK, P_RAKE_HI, P_RAKE_LO,
                         P_MAX_LOAD, P_RAKE_STEP, P_SID_TIP, P_SIZE, P_TID_FEE, P_W, ST_CUT_X, ST_CUT_Z, ST_FH, ST_FZ, ST_NEXT_CENTER, ST_RAKE, ST_SIZE, ST_TIP_PREV_X,
                         ST_ENGAGED, ST_W_IDEAL, fee_update, make_grids)
from .mjcf import attack_geometry, build_mjcf

WHEELS = ("wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr")
MATERIALS = ("homogeneous", "nonhomogeneous")
WINDUP = 0.02  # rad, largest lead of a hydraulic set-point over its joint


class AttackError(RuntimeError):
    """The machine did not bury the bucket d_init into the pile within the attack timeout."""


@dataclass
class FeeReport:
    """The last FEE evaluation (for tests, debugging and the sim node)."""
    force: np.ndarray      # world force on the bucket, N
    torque: np.ndarray     # world torque about the bucket CoM, N m
    depth: np.ndarray      # per engaged slice, m
    magnitude: float       # sum of F over slices before the speed ramp, N
    rake: float            # rad


class LhdSimulator:
    def __init__(self, cfg: dict):
        self.cfg = cfg
        self.p = TaskParams.from_config(cfg)
        self.soil = SoilRanges.from_config(cfg)
        self.model = mujoco.MjModel.from_xml_string(build_mjcf(cfg))
        self.data = mujoco.MjData(self.model)
        m = self.model
        pc, sc = cfg["pile"], cfg["sim"]
        self.fee_every = sc["fee_every"]
        n_phys = self.p.control_dt / m.opt.timestep
        if abs(n_phys - round(n_phys)) > 1e-6:
            raise ValueError(f"sim.timestep {m.opt.timestep} must divide the control period {self.p.control_dt}")
        self.n_phys = int(round(n_phys))
        if self.n_phys % self.fee_every:
            raise ValueError(f"sim.fee_every {self.fee_every} must divide the {self.n_phys} physics steps of a control period")
        self.fee_dt = self.fee_every * m.opt.timestep
        self.rake_attack = math.radians(pc["rake_attack_deg"])
        self.rake_lo = math.radians(pc["rake_min_deg"])
        self.rake_hi = math.radians(pc["rake_max_deg"])
        self.fee_min_speed = pc["fee_min_speed"]
        self.attack_timeout = sc["attack_timeout"]
        self.bucket_width = cfg["machine"]["bucket_width"]
        self.wheel_radius = cfg["machine"]["wheel_radius"]
        self.nonhomogeneous_probability = pc["nonhomogeneous_probability"]
        # ids
        self.bid_bucket = m.body("bucket").id
        self.sid_tip = m.site("tip").id
        self.sid_bottom = m.site("bottom").id
        self.tid_fee = m.tendon("fee_x").id
        self.wheel_dof = np.array([m.jnt_dofadr[m.joint(w).id] for w in WHEELS])
        self._wheel_dofs = [int(i) for i in self.wheel_dof]
        self.boom_q = m.jnt_qposadr[m.joint("boom").id]
        self.boom_v = m.jnt_dofadr[m.joint("boom").id]
        self.bucket_q = m.jnt_qposadr[m.joint("bucket").id]
        self.bucket_v = m.jnt_dofadr[m.joint("bucket").id]
        self.act_wheels = np.array([m.actuator(w).id for w in WHEELS])
        self.act_boom = m.actuator("boom").id
        self.act_bucket = m.actuator("bucket").id
        self.act_boom_adr = m.actuator_actadr[self.act_boom]
        self.act_bucket_adr = m.actuator_actadr[self.act_bucket]
        self._act_wheels = [int(a) for a in self.act_wheels]
        # views into MjData (valid for the life of self.data): cheaper than attribute lookups
        d = self.data
        self._ctrl, self._act, self._qpos, self._qvel = d.ctrl, d.act, d.qpos, d.qvel
        self._site_xpos, self._site_xmat = d.site_xpos, d.site_xmat
        self.bucket_mass0 = float(m.body_mass[self.bid_bucket])
        self.geometry = attack_geometry(cfg["machine"])
        self.pile: VoxelPile | None = None
        self.zones: Zones | None = None
        self.fee_enabled = True
        self._fee_h = self._fee_v = 0.0
        self._fee_rake = self.rake_attack
        self._fee_depth = ()
        self.use_kernel = True
        self.rake_step = math.radians(0.25)
        vx = cfg["paper"]["voxels"]
        self._grids, self._filled = make_grids(2, self.rake_lo, self.rake_hi, self.rake_step, len(BETA_GRID))
        self._kout = np.zeros(OUT_SIZE)
        self._kdepth = np.zeros(vx["n_y"])
        self._slices = np.zeros(0, dtype=int)

    # ------------------------------------------------------------------ episode set-up
    def new_pile(self, rng: np.random.Generator, alpha: float | None = None, material: str | None = None) -> None:
        p = self.p
        if alpha is None:
            alpha = rng.uniform(p.alpha_min, p.alpha_max)
        if material is None:
            material = "nonhomogeneous" if rng.random() < self.nonhomogeneous_probability else "homogeneous"
        if material not in MATERIALS:
            raise ValueError(f"material must be one of {MATERIALS}, got {material!r}")
        vx = self.cfg["paper"]["voxels"]
        self.pile = VoxelPile.generate(rng, alpha, p.h_pile, p.w_pile, vx["n_x"], vx["n_y"], vx["n_z"], self.soil,
                                       nonhomogeneous=(material == "nonhomogeneous"))
        self.material = material
        self.zones = Zones.for_pile(self.pile, p)
        s = self.soil
        gravel_phi = float(self.pile.phi[self.pile.klass == 0].flat[0]) if (self.pile.klass == 0).any() else s.rock_phi
        gravel_delta = float(self.pile.delta[self.pile.klass == 0].flat[0]) if (self.pile.klass == 0).any() else s.rock_delta
        self.fee_table = FeeTable(self.pile.alpha, (gravel_phi, s.rock_phi), (gravel_delta, s.rock_delta),
                                  rake_step=self.rake_step)
        self._phis = np.array([gravel_phi, s.rock_phi])
        self._deltas = np.array([gravel_delta, s.rock_delta])
        self._filled[:] = False

    def place_machine(self, d_attack: float) -> None:
        """Attack pose, at rest, bucket tip d_attack before the toe of the pile."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        d.qpos[0] = -d_attack - self.geometry["tip"][0]
        d.qpos[2] = self.geometry["r"]
        m.body_mass[self.bid_bucket] = self.bucket_mass0
        m.tendon_frictionloss[self.tid_fee] = 0.0
        mujoco.mj_forward(m, d)
        self.W_ideal = 0.0
        self.pile.removed_mass = 0.0
        self._slices = self.pile.slices_in(-self.bucket_width / 2, self.bucket_width / 2)
        self._tip_prev_x = float(d.site_xpos[self.sid_tip][0])
        self._cut_prev_x = self._tip_prev_x
        self._cut_prev_z = float(d.site_xpos[self.sid_tip][2])
        self._next_center = (math.floor(self._cut_prev_x / self.pile.dx - 0.5) + 1.5) * self.pile.dx
        self._n_slices = len(self._slices)
        self._fee_h = self._fee_v = 0.0
        d.xfrc_applied[:] = 0.0
        self._bind_kernel()

    def reset(self, rng: np.random.Generator, alpha: float | None = None, material: str | None = None,
              d_attack: float | None = None, attack_speed: float | None = None) -> None:
        """New pile, machine in the attack pose d_attack before it; drive in at attack_speed
        (rad/s at the wheels) with the arm still until the tip is d_init inside the pile."""
        p = self.p
        self.new_pile(rng, alpha, material)
        if d_attack is None:
            d_attack = rng.uniform(self.cfg["paper"]["episode"]["d_attack_min"], self.cfg["paper"]["episode"]["d_attack_max"])
        if attack_speed is None:
            attack_speed = rng.uniform(self.cfg["sim"]["attack_speed_min_fraction"], 1.0) * p.wheels_max
        self.d_attack, self.attack_speed = float(d_attack), float(attack_speed)
        self.place_machine(self.d_attack)
        t = 0.0
        self.set_command(np.array([self.attack_speed, 0.0, 0.0]))
        while self.data.site_xpos[self.sid_tip][0] < p.d_init:
            self._physics(self.fee_every)
            mujoco.mj_kinematics(self.model, self.data)
            t += self.fee_dt
            if self.use_kernel:
                self._sync_from_kernel()
            if t > self.attack_timeout:
                raise AttackError(f"the bucket did not reach d_init = {p.d_init} m inside the pile within "
                                  f"{self.attack_timeout} s (tip at x = {self.data.site_xpos[self.sid_tip][0]:.3f} m)")

    # ------------------------------------------------------------------ stepping
    def set_command(self, u: np.ndarray) -> None:
        """u = (u_wheels, u_boom, u_bucket) in rad/s, already within the actuator ranges."""
        ctrl = self._ctrl
        w = float(u[0])
        for a in self._act_wheels:
            ctrl[a] = w
        ctrl[self.act_boom] = u[1]
        ctrl[self.act_bucket] = u[2]

    def step(self, u: np.ndarray) -> None:
        """One control period with command u (rad/s)."""
        self.set_command(u)
        self._anti_windup()
        for _ in range(self.n_phys // self.fee_every):
            self._physics(self.fee_every)
        mujoco.mj_kinematics(self.model, self.data)
        if self.use_kernel:
            self._sync_from_kernel()

    def advance(self, u: np.ndarray) -> None:
        """One FEE period (``fee_every`` physics steps: 20 ms at the shipped config) with command
        u (rad/s): the real-time chunk of the digital twin (lhd_sim_node/sim_due.py), whose device
        loop changes the command at this grain. The same anti-windup, FEE update, kinematics
        refresh and kernel sync as ``step`` (and as the attack loop of ``reset``), so the state
        read after it (``state()``, ``loaded_mass``, ``last_fee``) is current. ``step`` is
        unchanged: five ``advance`` calls are not bit-identical to one ``step`` (step refreshes
        the kinematics and pulls the servo set-points back once per control period, advance
        once per chunk), but both integrate the same model."""
        self.set_command(u)
        self._anti_windup()
        self._physics(self.fee_every)
        mujoco.mj_kinematics(self.model, self.data)
        if self.use_kernel:
            self._sync_from_kernel()

    def _physics(self, n: int) -> None:
        if self.fee_enabled:
            if self.use_kernel:
                self._update_fee()
            else:
                self._update_fee_numpy()
        mujoco.mj_step(self.model, self.data, nstep=n)

    def _anti_windup(self) -> None:
        """A blocked hydraulic joint does not store the commanded motion: at every control
        period the servo's integrated set-point is pulled back to within WINDUP of the
        joint's actual position (a period at full speed leads by at most 0.02 rad)."""
        act, qpos = self._act, self._qpos
        for a, q in ((self.act_boom_adr, self.boom_q), (self.act_bucket_adr, self.bucket_q)):
            act[a] = min(max(act[a], qpos[q] - WINDUP), qpos[q] + WINDUP)

    def _update_fee_numpy(self) -> None:
        """Reference implementation of one FEE update in numpy (the kernel must match it)."""
        d, pile = self.data, self.pile
        tip = d.site_xpos[self.sid_tip]
        x, z = float(tip[0]), float(tip[2])
        # cutting: the columns whose centre the tip passed lose the material above the tip
        if x >= self._next_center:
            m = pile.cut(self._cut_prev_x, self._cut_prev_z, x, z, self._slices)
            self._next_center = (math.floor(x / pile.dx - 0.5) + 1.5) * pile.dx
            if m > 0.0:
                self.W_ideal += m
                self.model.body_mass[self.bid_bucket] = self.bucket_mass0 + self.loaded_mass
        elif x < self._cut_prev_x:  # moved back: the next centre ahead may be an earlier one
            self._next_center = (math.floor(x / pile.dx - 0.5) + 1.5) * pile.dx
        self._cut_prev_x, self._cut_prev_z = x, z
        v_tip = (x - self._tip_prev_x) / self.fee_dt
        self._tip_prev_x = x
        # the material ahead of the tip: the first column whose centre the tip has not passed
        xa = x + 0.5 * pile.dx
        xfrc = d.xfrc_applied[self.bid_bucket]
        if x < 0.0 or xa >= pile.L or self._n_slices == 0:
            self._no_fee(xfrc)
            return
        i = int(xa / pile.dx)
        depth = pile.top[self._slices, i] - z
        if depth.max() <= 0.0:
            self._no_fee(xfrc)
            return
        j = self._slices
        if depth.min() <= 0.0:
            keep = depth > 0.0
            j, depth = j[keep], depth[keep]
        xmat = d.site_xmat[self.sid_tip]
        pitch = math.atan2(xmat[6], xmat[0])  # x-axis of the tip frame: (xmat[0], xmat[3], xmat[6])
        rake = min(max(self.rake_attack - pitch, self.rake_lo), self.rake_hi)
        # soil of each slice: the voxel at mid-depth of the layer above the tip
        k = ((z + 0.5 * depth) * pile.inv_dz).astype(np.intp)
        np.clip(k, 0, pile.n_z - 1, out=k)
        gamma = pile.density[j, i, k]
        coh = pile.cohesion[j, i, k]
        klass = pile.klass[j, i, k]
        if not klass.any():
            F, s_, c_ = self.fee_table.force(0, depth, pile.dy, gamma, coh, pile.surcharge, pile.adhesion, rake)
            fh = F * s_
            fv = F * c_
        else:
            fh = np.empty(len(j))
            fv = np.empty(len(j))
            for kl in (0, 1):
                sel = klass == kl
                if sel.any():
                    F, s_, c_ = self.fee_table.force(kl, depth[sel], pile.dy, gamma[sel], coh[sel], pile.surcharge,
                                                     pile.adhesion, rake)
                    fh[sel] = F * s_
                    fv[sel] = F * c_
        # Horizontal: dry friction on the x-tendon (resists motion up to F sin(rake+delta), no creep).
        fh_sum = float(fh.sum())
        self.model.tendon_frictionloss[self.tid_fee] = fh_sum
        # Vertical: F cos(rake+delta) downward, mobilised while the tip advances into the pile.
        ramp = min(max(v_tip / self.fee_min_speed, 0.0), 1.0)
        fz_sum = -ramp * float(fv.sum())
        com = d.xipos[self.bid_bucket]
        # torque about the CoM of the vertical slice forces applied at the tip: r x (0, 0, fz)
        xfrc[2] = fz_sum
        xfrc[3] = -ramp * float(np.dot(pile.y_centers[j] - com[1], fv))
        xfrc[4] = -(x - float(com[0])) * fz_sum
        self._fee_h, self._fee_v, self._fee_rake, self._fee_depth = fh_sum, fz_sum, rake, depth

    def _update_fee(self) -> None:
        """One FEE update (compiled kernel): cut the pile, set the horizontal resistance on the
        tendon and the vertical force and its torque in xfrc_applied."""
        fee_update(*self._kargs)

    def _bind_kernel(self) -> None:
        """Bind the kernel's arguments once per episode (views into MuJoCo's and the pile's arrays)."""
        m, d, pile = self.model, self.data, self.pile
        st = np.zeros(ST_SIZE)
        st[ST_CUT_X], st[ST_CUT_Z] = self._cut_prev_x, self._cut_prev_z
        st[ST_NEXT_CENTER], st[ST_TIP_PREV_X] = self._next_center, self._tip_prev_x
        st[ST_RAKE] = self.rake_attack
        self._kst = st
        par = np.zeros(P_SIZE)
        par[[P_SID_TIP, P_BID_BUCKET, P_TID_FEE]] = self.sid_tip, self.bid_bucket, self.tid_fee
        par[[P_BUCKET_MASS0, P_LOADED_FRACTION, P_FEE_DT, P_FEE_MIN_SPEED]] = (
            self.bucket_mass0, self.p.loaded_fraction, self.fee_dt, self.fee_min_speed)
        par[[P_DX, P_DZ, P_L, P_H, P_W, P_Q, P_CA, P_ALPHA]] = (
            pile.dx, pile.dz, pile.L, pile.h, pile.dy, pile.surcharge, pile.adhesion, pile.alpha)
        par[[P_RAKE_ATTACK, P_RAKE_LO, P_RAKE_HI, P_RAKE_STEP]] = self.rake_attack, self.rake_lo, self.rake_hi, self.rake_step
        par[P_MAX_LOAD] = self.p.bucket_max_load
        self._kargs = (d.site_xpos, d.site_xmat, d.xipos, d.xfrc_applied, m.tendon_frictionloss, m.body_mass, st, par,
                       self._slices, pile.top, pile._cum, pile._voxel_mass, pile.density, pile.cohesion, pile.klass,
                       pile.x_centers, pile.y_centers, self._grids, self._filled, self._phis, self._deltas, BETA_GRID,
                       self._kdepth, self._kout)

    def _sync_from_kernel(self) -> None:
        st = self._kst
        self.W_ideal = st[ST_W_IDEAL]
        self.pile.removed_mass = st[ST_W_IDEAL]
        self._cut_prev_x, self._cut_prev_z = st[ST_CUT_X], st[ST_CUT_Z]
        self._next_center, self._tip_prev_x = st[ST_NEXT_CENTER], st[ST_TIP_PREV_X]
        self._fee_h, self._fee_v, self._fee_rake = st[ST_FH], st[ST_FZ], st[ST_RAKE]
        self._fee_depth = self._kdepth[self._kdepth > 0.0].copy() if st[ST_ENGAGED] else ()

    @property
    def last_fee(self) -> FeeReport:
        xf = self.data.xfrc_applied[self.bid_bucket]
        return FeeReport(np.array([-self._fee_h, 0.0, self._fee_v]), xf[3:].copy(), np.asarray(self._fee_depth),
                         math.hypot(self._fee_h, self._fee_v), self._fee_rake)

    def _no_fee(self, xfrc) -> None:
        if self._fee_h != 0.0 or self._fee_v != 0.0:
            xfrc[:] = 0.0
            self.model.tendon_frictionloss[self.tid_fee] = 0.0
        self._fee_h, self._fee_v, self._fee_depth = 0.0, 0.0, ()

    # ------------------------------------------------------------------ readings
    @property
    def loaded_mass(self) -> float:
        """Payload W: 2/3 of the mass cut from the pile (paper), up to the bucket's heaped
        capacity; the rest spills."""
        return min(self.p.loaded_fraction * self.W_ideal, self.p.bucket_max_load)

    def wheel_drift(self) -> tuple[bool, bool]:
        """(front, rear): a wheel drifts when its rim speed and the chassis speed differ by
        more than max(drift_min_speed, drift_slip_ratio * the larger of the two)."""
        p = self.p
        qv = self._qvel
        v = float(qv[0])
        slip = []
        for dof in self._wheel_dofs:
            rim = qv[dof] * self.wheel_radius
            slip.append(abs(rim - v) > max(p.drift_min_speed, p.drift_slip_ratio * max(abs(rim), abs(v))))
        return slip[0] or slip[1], slip[2] or slip[3]

    def state(self) -> LhdState:
        x_tip, y_tip, z_tip = self._site_xpos[self.sid_tip].tolist()
        xmat = self._site_xmat[self.sid_tip]
        x_b, _, z_b = self._site_xpos[self.sid_bottom].tolist()
        qpos, qvel = self._qpos, self._qvel
        front, rear = self.wheel_drift()
        return LhdState(
            x_shovel=x_tip, y_shovel=y_tip, z_shovel=z_tip, phi_shovel=math.atan2(xmat[6], xmat[0]),
            v_x=float(qvel[0]), drift=front or rear,
            phi_boom=float(qpos[self.boom_q]), dphi_boom=float(qvel[self.boom_v]),
            phi_bucket=float(qpos[self.bucket_q]), dphi_bucket=float(qvel[self.bucket_v]),
            x_bottom=x_b, z_bottom=z_b, drift_front=front, drift_rear=rear,
        )

    def wheel_speeds(self) -> np.ndarray:
        """(fl, fr, rl, rr) rad/s."""
        return self.data.qvel[self.wheel_dof].copy()
