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
from collections import deque
from dataclasses import dataclass

import mujoco
import numpy as np

from lhd_loading_ros.task.kinematics import nose_down_pitch
from lhd_loading_ros.task.params import TaskParams
from lhd_loading_ros.task.pile import SoilRanges, VoxelPile
from lhd_loading_ros.task.randomization import NOMINAL, Conditions, delay_chunks
from lhd_loading_ros.task.state import LhdState
from lhd_loading_ros.task.zones import Zones

from lhd_loading_ros.task.bucket_capacity import capacity_table

from .fee import BETA_GRID, slice_force
from .fee_kernel import (OUT_SIZE, P_BID_BUCKET, P_BUCKET_MASS0, P_CA, P_DX, P_DZ, P_FEE_DT, P_FEE_MIN_SPEED, P_H, P_L,
                         P_LOADED_FRACTION, P_Q, P_RAKE_ATTACK, P_RAKE_HI, P_RAKE_LO, P_SID_TIP, P_SIZE, P_TID_FEE, P_W,
                         ST_ALPHA_S, ST_CUT_X, ST_CUT_Z, ST_ENGAGED, ST_FH, ST_FZ, ST_M_BUCKET, ST_NEXT_CENTER, ST_RAKE,
                         ST_SIZE, ST_SPILLED, ST_TIP_PREV_X, ST_TIP_PREV_Z, ST_V_BUCKET, ST_V_CUT, ST_W_IDEAL, P_BY_MOTION,
                         ST_MOBILISED, P_WEDGE_TAU, beta_tables, fee_update, wedge_mobilisation)
from .mjcf import attack_geometry, build_mjcf
from . import fused
from .bucket_body import BucketBody, bucket_body_update
from .fused import run_attack, run_chunks, run_chunks_marked

WHEELS = ("wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr")
MATERIALS = ("homogeneous", "nonhomogeneous")
WINDUP = 0.02  # rad, largest lead of a hydraulic set-point over its joint


class SimulationError(RuntimeError):
    """MuJoCo found the state unstable (non-finite or huge accelerations) and reset it."""


class AttackError(RuntimeError):
    """The machine did not bury the bucket d_init into the pile within the attack timeout."""


REST_SPEED = 0.005     # m/s: the machine and every wheel rim slower than this stand still (a start from rest)
REST_TIMEOUT = 3.0     # s: a machine still moving this long after its wheels were stopped is an AttackError
DRIFT_LAG_LIMIT_S = 0.5   # s: the longest drift-window lag the chunk history serves (config schema's limit of
                          # randomization.drift_flag_lag_max_s)


@dataclass
class FeeReport:
    """The last FEE evaluation (for tests, debugging and the sim node)."""
    force: np.ndarray      # world force on the bucket, N
    torque: np.ndarray     # world torque about the bucket CoM, N m
    depth: np.ndarray      # per engaged slice, m, normal to the local surface ahead of the lip
    magnitude: float       # sum of F over slices before the speed ramp, N
    rake: float            # rad, world rake of the bucket (rake_attack - pitch, clipped)
    alpha_s: float = 0.0   # rad, mean slope of the local surface ahead of the lip over the engaged slices
    mobilised: float = 1.0  # share of the lip's wedge the tip's motion mobilises (fee_kernel.wedge_mobilisation)


class LhdSimulator:
    # what points into this simulator's own MjData / MjModel: views and the raw C addresses the compiled loop
    # takes. A copy or an unpickled simulator binds them to its own data again (__setstate__): a review found
    # copy.deepcopy(env) stepping the original's physics and an unpickled env crashing (segmentation fault)
    _BOUND = ("_ctrl", "_act", "_qpos", "_qvel", "_site_xpos", "_site_xmat", "_pm", "_pd")

    def _bind_views(self) -> None:
        # views into MjData (valid for the life of self.data): cheaper than attribute lookups
        d = self.data
        self._ctrl, self._act, self._qpos, self._qvel = d.ctrl, d.act, d.qpos, d.qvel
        self._site_xpos, self._site_xmat = d.site_xpos, d.site_xmat
        self._pm, self._pd = (self.model._address, self.data._address) if getattr(self, "fused", False) else (0, 0)

    def __getstate__(self) -> dict:
        st = {k: v for k, v in self.__dict__.items() if k not in self._BOUND}
        del st["model"]              # the data carries its own copy of the model, which it was made with
        return st

    def __setstate__(self, st: dict) -> None:
        self.__dict__.update(st)
        self.model = self.data.model
        self._bind_views()
        if getattr(self, "_kargs", None) is not None:
            # the kernel's views into MuJoCo's arrays came over as detached copies: the FEE force would go into
            # an array the physics never reads. Those of this data and model instead (the rest, the pile's arrays
            # and the kernel's state, came over with the same identities as the attributes that hold them)
            d, m = self.data, self.model
            self._kargs = (d.site_xpos, d.site_xmat, d.xipos, d.xfrc_applied, m.tendon_frictionloss, m.body_mass,
                           *self._kargs[6:])
        if getattr(self, "_body_args", None) is not None:        # the whole bucket's kernel (bucket_body.bind)
            self._body_args = self.body.args = (self.data.xpos, self.data.xmat, self.model.body_mass,
                                                self.model.dof_frictionloss, self.model.tendon_frictionloss,
                                                *self._body_args[5:])

    def __init__(self, cfg: dict, articulation_hinge: bool = False):
        """articulation_hinge=True: the machine model before 2026-11-26, its articulation a hinge
        locked by an equality constraint (mjcf.build_mjcf; for comparisons), not a rigid joint."""
        self.cfg = cfg
        self.p = TaskParams.from_config(cfg)
        self.soil = SoilRanges.from_config(cfg)
        self.model = mujoco.MjModel.from_xml_string(build_mjcf(cfg, articulation_hinge=articulation_hinge))
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
        self.fee_by_motion = int(pc["fee_wedge_by_motion"])
        self.fee_wedge_tau = float(pc["fee_wedge_tau"])
        self.attack_timeout = sc["attack_timeout"]
        self.attack_min_depth = float(sc.get("attack_min_depth", 0.0))
        self.attack_stalled = False      # the last reset's attack stalled short of d_init and started there
        self.bucket_width = cfg["machine"]["bucket_width"]
        self.wheel_radius = cfg["machine"]["wheel_radius"]
        self.nonhomogeneous_probability = pc["nonhomogeneous_probability"]
        # ids
        self.bid_bucket = m.body("bucket").id
        self.bid_rear = m.body("rear_frame").id
        self.sid_tip = m.site("tip").id
        self.sid_bottom = m.site("bottom").id
        self.tid_fee = m.tendon("fee_x").id
        self.body = BucketBody(cfg, m)  # breakout and ploughing of the whole bucket (bucket_body.py)
        self.wheel_dof = np.array([m.jnt_dofadr[m.joint(w).id] for w in WHEELS])
        self._wheel_dofs = [int(i) for i in self.wheel_dof]
        self._wheel_geoms = [m.geom(w).id for w in WHEELS]
        self._tyre_friction0 = float(m.geom_friction[self._wheel_geoms[0], 0])
        # domain randomisation (task/randomization.py): chunks of a control period that still run
        # the previous command (drive, hydraulics), and that command
        self._delay_chunks = (0, 0)
        self._gains = (1.0, 1.0)                 # actuator gains of the episode (conditions)
        self._u_prev = np.zeros(3)
        self.conditions = NOMINAL
        # drift over a window of one control period (wheel_drift): the marks (time, x, wheel angles)
        # at the start of the last chunks; advance() and the attack drive keep the last n of them
        self._wheel_qs = [int(m.jnt_qposadr[m.joint(w).id]) for w in WHEELS]
        self._wheel_qs_arr = np.array(self._wheel_qs, dtype=np.int64)
        self._drift_marks: deque = deque(maxlen=max(1, self.n_phys // self.fee_every))
        self._drift_from: tuple = ()
        # the marks at every chunk boundary of the last DRIFT_LAG_LIMIT_S + a control period, kept while the
        # episode's conditions lag the observed drift window (conditions.drift_flag_lag_max_s; drift_flag)
        n_chunks = max(1, self.n_phys // self.fee_every)
        self._chunk_hist: deque = deque(maxlen=n_chunks + int(math.ceil(DRIFT_LAG_LIMIT_S / (self.fee_every * m.opt.timestep)
                                                                          - 1e-9)) + 1)
        self._hist_marks = np.zeros((n_chunks, 2 + len(WHEELS)))
        self._keep_hist = False
        self.boom_q = m.jnt_qposadr[m.joint("boom").id]
        self.boom_v = m.jnt_dofadr[m.joint("boom").id]
        self.bucket_q = m.jnt_qposadr[m.joint("bucket").id]
        self.bucket_v = m.jnt_dofadr[m.joint("bucket").id]
        # drive motors: one per wheel, or (machine.rear_differential) one per front wheel and one
        # for the rear differential ("wheel_r"); every motor takes the same wheel-speed command
        names = [m.actuator(i).name for i in range(m.nu)]
        self.act_wheels = np.array([m.actuator(w).id for w in (*WHEELS, "wheel_r") if w in names])
        # the motor whose torque each wheel of WHEELS gets, and the share of it
        self._wheel_torque_from = [(m.actuator(w).id, 1.0) if w in names else (m.actuator("wheel_r").id, 0.5)
                                   for w in WHEELS]
        self.act_boom = m.actuator("boom").id
        self.act_bucket = m.actuator("bucket").id
        self.act_boom_adr = m.actuator_actadr[self.act_boom]
        self.act_bucket_adr = m.actuator_actadr[self.act_bucket]
        self._act_wheels = [int(a) for a in self.act_wheels]
        self._bind_views()
        self.bucket_mass0 = float(m.body_mass[self.bid_bucket])
        self.geometry = attack_geometry(cfg["machine"])
        self.pile: VoxelPile | None = None
        self.zones: Zones | None = None
        self.fee_enabled = True
        self._fee_h = self._fee_v = 0.0
        self._fee_rake = self.rake_attack
        self._fee_depth = ()
        self.use_kernel = True
        # chunks run in one compiled loop that calls MuJoCo's C API (fused.py; bit-identical to
        # _physics + mujoco.mj_kinematics); False keeps the Python-driven loop (the bench's
        # recording run sets it, to see every chunk)
        self.fused = fused.AVAILABLE
        self._attack_marks = np.zeros((int(self.attack_timeout / (self.fee_every * m.opt.timestep)) + 2,
                                       2 + len(WHEELS)))
        self._pm, self._pd = (self.model._address, self.data._address) if self.fused else (0, 0)   # (_bind_views too)
        vx = cfg["paper"]["voxels"]
        # the bucket's geometric capacity (m^3, struck + heap at repose) over the tip pitch (H4's table)
        cap_pitch, cap_vol = capacity_table(cfg)
        self._cap_pitch = np.ascontiguousarray(cap_pitch, dtype=float)
        self._cap_vol = np.ascontiguousarray(cap_vol, dtype=float)
        self._alpha_s = 0.0
        self._kout = np.zeros(OUT_SIZE)
        self._kdepth = np.zeros(vx["n_y"])
        self._slices = np.zeros(0, dtype=int)

    # ------------------------------------------------------------------ episode set-up
    def new_pile(self, rng: np.random.Generator, alpha: float | None = None, material: str | None = None,
                 soil: SoilRanges | None = None, surface_sd: float = 0.0, surface_corr: float = 0.15) -> None:
        """A new pile of slope alpha and material (drawn when None); soil: ranges to draw its
        parameters from (default the config's pile ranges; domain randomisation widens them);
        surface_sd > 0: a random relief of that sd (m) and correlation length surface_corr about the
        plane (VoxelPile.roughen; drawn from rng after the pile, so a plane pile draws as before)."""
        p = self.p
        if alpha is None:
            alpha = rng.uniform(p.alpha_min, p.alpha_max)
        if material is None:
            material = "nonhomogeneous" if rng.random() < self.nonhomogeneous_probability else "homogeneous"
        if material not in MATERIALS:
            raise ValueError(f"material must be one of {MATERIALS}, got {material!r}")
        vx = self.cfg["paper"]["voxels"]
        self.pile = VoxelPile.generate(rng, alpha, p.h_pile, p.w_pile, vx["n_x"], vx["n_y"], vx["n_z"],
                                       self.soil if soil is None else soil,
                                       nonhomogeneous=(material == "nonhomogeneous"))
        if surface_sd > 0.0:
            self.pile.roughen(rng, surface_sd, surface_corr)
        self.material = material
        self.zones = Zones.for_pile(self.pile, p)
        s = self.soil
        gravel_phi = float(self.pile.phi[self.pile.klass == 0].flat[0]) if (self.pile.klass == 0).any() else s.rock_phi
        gravel_delta = float(self.pile.delta[self.pile.klass == 0].flat[0]) if (self.pile.klass == 0).any() else s.rock_delta
        self._phis = np.array([gravel_phi, s.rock_phi])
        self._deltas = np.array([gravel_delta, s.rock_delta])
        self._tabs = beta_tables(self._phis, BETA_GRID)  # the FEE kernel's beta-only terms per class

    _UNSTABLE = (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADQACC)

    def _instability_count(self) -> int:
        """How often MuJoCo has reset this data for a non-finite or huge position, velocity or
        acceleration (mj_step's checks; the counts survive the reset)."""
        return sum(int(self.data.warning[w].number) for w in self._UNSTABLE)

    def _warning_summary(self) -> str:
        return ", ".join(f"{w.name} {int(self.data.warning[w].number)}" for w in self._UNSTABLE)

    def place_machine(self, d_attack: float, heading: float = 0.0, lateral: float = 0.0) -> None:
        """Attack pose, at rest, bucket tip d_attack before the toe of the pile; heading (rad, yaw,
        positive turns the nose to +y) and lateral (m, the lip centre's y) for a machine placed by
        hand. The bucket's slices of the pile are those under the lip where it starts (the lip
        moves 2.6 cm sideways over a 0.5 m attack at 3 deg: the FEE keeps the start's slices)."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        tip = self.geometry["tip"][0]
        d.qpos[0] = -d_attack - tip * math.cos(heading)
        d.qpos[1] = lateral - tip * math.sin(heading)
        d.qpos[2] = self.geometry["r"]
        d.qpos[3:7] = (math.cos(heading / 2), 0.0, 0.0, math.sin(heading / 2))
        m.body_mass[self.bid_bucket] = self.bucket_mass0
        m.tendon_frictionloss[self.tid_fee] = 0.0
        mujoco.mj_forward(m, d)
        self.W_ideal = 0.0
        self.pile.removed_mass = 0.0
        # payload: loaded_fraction of the cut volume and mass, up to the bucket's geometric capacity
        self.V_cut = 0.0        # m^3 cut from the pile
        self._v_bucket = 0.0    # m^3 in the bucket
        self._m_bucket = 0.0    # kg in the bucket (= loaded_mass)
        self._spilled = 0.0     # kg loaded beyond the capacity and spilled
        self._alpha_s = 0.0
        y_lip = float(d.site_xpos[self.sid_tip][1])
        self._slices = self.pile.slices_in(y_lip - self.bucket_width / 2, y_lip + self.bucket_width / 2)
        self._tip_prev_x = float(d.site_xpos[self.sid_tip][0])
        self._tip_prev_z = float(d.site_xpos[self.sid_tip][2])
        self._cut_prev_x = self._tip_prev_x
        self._cut_prev_z = self._tip_prev_z
        self._mobilised = 1.0
        self._next_center = (math.floor(self._cut_prev_x / self.pile.dx - 0.5) + 1.5) * self.pile.dx
        self._n_slices = len(self._slices)
        self._fee_h = self._fee_v = 0.0
        d.xfrc_applied[:] = 0.0
        self._drift_marks.clear()
        self._drift_from = self._drift_mark()  # drift window: none yet (wheel_drift)
        self._chunk_hist.clear()
        self._bind_kernel()
        self._body_args = self.body.bind(m, d, self.pile, self._slices, self.bucket_mass0)

    def machine_pitch(self) -> float:
        """The rear frame's pitch in the world, rad, nose-down positive: the angle its x axis
        makes with the floor, x_axis = (cos p cos yaw, cos p sin yaw, -sin p), whatever the
        heading. What a pitch sensor on the machine would read; the task's bucket pitch
        (phi_shovel) is in the world frame and already includes it."""
        return nose_down_pitch(self.data.xmat[self.bid_rear].reshape(3, 3))

    def reset(self, rng: np.random.Generator, alpha: float | None = None, material: str | None = None,
              d_attack: float | None = None, attack_speed: float | None = None,
              conditions: Conditions | None = None) -> None:
        """New pile, machine in the attack pose d_attack before it; drive in at attack_speed
        (rad/s at the wheels) with the arm still until the tip is d_init inside the pile.
        conditions (task/randomization.py): the episode's physical departures (soil ranges, tyre
        friction, start distance, attack speed, heading, lateral offset, actuator delays);
        explicit d_attack / attack_speed win over theirs. NOMINAL (the default) draws exactly what
        the simulator drew before conditions existed."""
        p = self.p
        c = NOMINAL if conditions is None else conditions
        lag = c.drift_flag_lag_max_s
        n_lag = round(lag / self.fee_dt) if isinstance(lag, (int, float)) and math.isfinite(lag) else -1
        if not (0 <= n_lag * self.fee_dt <= DRIFT_LAG_LIMIT_S + 1e-9 and abs(n_lag * self.fee_dt - lag) <= 1e-9):
            raise ValueError(f"conditions.drift_flag_lag_max_s {lag!r} s: expected a multiple of the {self.fee_dt:g} s "
                             f"chunk in 0..{DRIFT_LAG_LIMIT_S:g} s (randomization.drift_flag_lag_max_s)")
        self._keep_hist = lag > 0.0
        self.conditions = c
        self.new_pile(rng, alpha, material, soil=c.soil, surface_sd=c.surface_sd, surface_corr=c.surface_corr)
        if d_attack is None:
            d_attack = c.d_attack if c.d_attack is not None else rng.uniform(
                self.cfg["paper"]["episode"]["d_attack_min"], self.cfg["paper"]["episode"]["d_attack_max"])
        if attack_speed is None:
            frac = c.attack_speed_fraction if c.attack_speed_fraction is not None else rng.uniform(
                self.cfg["sim"]["attack_speed_min_fraction"], 1.0)
            attack_speed = frac * p.wheels_max
        mu = self._tyre_friction0 if c.tyre_friction is None else float(c.tyre_friction)
        for g in self._wheel_geoms:
            self.model.geom_friction[g, 0] = mu
        chunks = self.n_phys // self.fee_every
        self._delay_chunks = (delay_chunks(c.drive_delay_s, self.fee_dt, chunks),
                              delay_chunks(c.hydraulic_delay_s, self.fee_dt, chunks))
        if not (c.drive_gain > 0.0 and c.hydraulic_gain > 0.0):
            raise ValueError(f"actuator gains drive {c.drive_gain!r}, hydraulics {c.hydraulic_gain!r}: expected > 0")
        self._gains = (float(c.drive_gain), float(c.hydraulic_gain))
        self.d_attack, self.attack_speed = float(d_attack), float(attack_speed)
        self.place_machine(self.d_attack, math.radians(c.heading_deg), c.lateral_offset)
        t = 0.0
        self.set_command(np.array([self.attack_speed, 0.0, 0.0]))
        self._u_prev = np.array([self.attack_speed, 0.0, 0.0])
        self._drift_marks.clear()
        tip = self._site_xpos[self.sid_tip]
        # drive in, recording the drift marks, until the tip is d_init inside the pile or the
        # timeout passes: compiled (fused.run_attack) where it can, else the Python loop below
        warnings0 = self._instability_count()
        now = None
        if self.fused and self.use_kernel:
            marks = self._attack_marks
            n, timed_out, now = run_attack(self._pm, self._pd, self.fee_every, self.fee_enabled, self._kargs,
                                      self._body_args, self._site_xpos, self.sid_tip, p.d_init, self.fee_dt,
                                      self.attack_timeout, self.data.time, self.model.opt.timestep, self._qpos,
                                      self._wheel_qs_arr, marks)
            for k in range(max(0, n - self._drift_marks.maxlen), n):
                self._drift_marks.append(tuple(marks[k].tolist()))
            if self._keep_hist:
                for k in range(max(0, n - self._chunk_hist.maxlen), n):
                    self._chunk_hist.append(tuple(marks[k].tolist()))
            if n:
                self._drift_from = self._drift_marks[0]
            t = self.attack_timeout + 1.0 if timed_out else 0.0
        while t <= self.attack_timeout and tip[0] < p.d_init:
            self._drift_marks.append(self._drift_mark())
            if self._keep_hist:
                self._chunk_hist.append(self._drift_mark())
            self._drift_from = self._drift_marks[0]
            self._chunks(1)
            t += self.fee_dt
        if self._keep_hist:
            self._chunk_hist.append(self._drift_mark())    # the boundary after the drive's last chunk
        # an instability inside the drive: mj_step reset the data (its time to 0) and counted a warning
        if self._instability_count() != warnings0 or (now is not None and abs(now - self.data.time) > 1e-6):
            raise SimulationError(
                f"MuJoCo found the state unstable during the attack drive and reset it (time {self.data.time:.4f} s"
                f"{'' if now is None else f', expected {now:.4f} s'}; {self._warning_summary()}); expected a finite, "
                "stable state: the pile, the conditions or the model's timestep are outside what the simulator handles")
        self.attack_stalled = False
        if t > self.attack_timeout:
            if self.use_kernel:
                self._sync_from_kernel()
            x_tip = float(self.data.site_xpos[self.sid_tip][0])
            # the last chunk may reach d_init as the time runs out: not a stall
            if x_tip < p.d_init:
                if not 0.0 < self.attack_min_depth <= x_tip:
                    raise AttackError(f"the bucket did not reach d_init = {p.d_init} m inside the pile within "
                                      f"{self.attack_timeout} s (tip at x = {x_tip:.3f} m)")
                # sim.attack_min_depth: the drive buried the tip this far and could push it no further (a
                # steep pile of a strong material, a slow attack): the episode starts where the machine
                # stands, as an operator arms the machine wherever the drive in stopped
                self.attack_stalled = True
        elif self.use_kernel:     # the kernel's state accumulates in self._kst: read it once, after the drive
            self._sync_from_kernel()
        if c.rest_start:
            self.come_to_rest()
            # armed after the machine stood: the drift windows reaching before now see it stand (drift_flag)
            self._chunk_hist.clear()
            if self._keep_hist:
                self._chunk_hist.append(self._drift_mark())

    def come_to_rest(self) -> None:
        """Every actuator commanded to zero, one FEE chunk at a time, until the machine and its
        wheels stand (all slower than REST_SPEED): how an attempt starts on the machine and in the
        digital twin, where the machine stands in the attack pose with the tip in the pile when the
        supervisor arms (placed there by hand, or stopped there after the drive in), instead of
        hitting the pile at the attack speed as the paper's episodes do. The first period after it
        then accelerates the machine from rest, bucket in the pile (the tyres may slip: the drift
        flags of a start from rest are physical, docs/modeling.md "A start from rest"). The tip
        ends at or beyond d_init (the machine coasts a little), or where a stalled drive left it
        (sim.attack_min_depth). AttackError if it does not stand
        within REST_TIMEOUT."""
        zero = np.zeros(3)
        r = self.wheel_radius
        t = 0.0
        while True:
            self.advance(zero)
            t += self.fee_dt
            if abs(float(self._qvel[0])) < REST_SPEED and float(np.max(np.abs(self.wheel_speeds()))) * r < REST_SPEED:
                break
            if t > REST_TIMEOUT:
                raise AttackError(f"the machine did not come to rest within {REST_TIMEOUT} s of stopping its wheels "
                                  f"(v_x {float(self._qvel[0]):.3f} m/s); expected it to stand in the pile")
        self._u_prev = zero      # the previous command was zero: a dead time runs zero in the first period

    # ------------------------------------------------------------------ stepping
    def set_command(self, u: np.ndarray) -> None:
        """u = (u_wheels, u_boom, u_bucket) in rad/s, already within the actuator ranges. The
        episode's actuator gains (conditions: 1 nominal) scale what the actuators are asked for:
        the machine's wheels and hydraulics turn slower or faster than commanded, unseen by the
        controller."""
        ctrl = self._ctrl
        g_drive, g_hyd = self._gains
        w = float(u[0]) * g_drive
        for a in self._act_wheels:
            ctrl[a] = w
        ctrl[self.act_boom] = u[1] * g_hyd
        ctrl[self.act_bucket] = u[2] * g_hyd

    def step(self, u: np.ndarray) -> None:
        """One control period with command u (rad/s). With actuator dead time (conditions), the
        first chunks of the period still run the previous period's command on that channel."""
        u = np.array(u, dtype=float)
        dd, dh = self._delay_chunks
        prev = self._u_prev
        self._drift_marks.clear()
        self._drift_from = self._drift_mark()
        chunks = self.n_phys // self.fee_every
        changes = sorted({0, *(k for k in (dd, dh) if 0 < k < chunks)})   # the command changes: set it,
        for i, k in enumerate(changes):                                    # pull the set-points back
            self.set_command(np.array([prev[0] if k < dd else u[0], prev[1] if k < dh else u[1],
                                       prev[2] if k < dh else u[2]]))
            self._anti_windup()
            last = i == len(changes) - 1
            self._chunks((chunks if last else changes[i + 1]) - k, kinematics=last, record=self._keep_hist)
        self._check_stable()
        if self.use_kernel:
            self._sync_from_kernel()
        self._u_prev = u

    def _check_stable(self) -> None:
        """MuJoCo resets the data (time back to 0) when it finds a non-finite or huge position,
        velocity or acceleration; a period that ends at or before its start time had one. The
        episode cannot go on from a machine teleported to its initial pose: SimulationError."""
        if self.data.time <= self._drift_from[0]:
            raise SimulationError(
                f"MuJoCo found the state unstable and reset it (time {self.data.time:.4f} s after "
                f"{self._drift_from[0]:.4f} s; {self._warning_summary()}); the episode cannot continue: reset it")

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
        self._drift_marks.append(self._drift_mark())
        self._drift_from = self._drift_marks[0]
        self._chunks(1, record=self._keep_hist)
        self._check_stable()
        if self.use_kernel:
            self._sync_from_kernel()

    def _chunks(self, n: int, kinematics: bool = True, record: bool = False) -> None:
        """n FEE chunks (each: _physics(fee_every)), then mj_kinematics if kinematics, in one
        compiled call where it can (fused.py), else driven from Python: the same states. record:
        the drift mark after each chunk goes to the chunk history (drift_flag)."""
        if self.fused and self.use_kernel:
            if record:
                marks = self._hist_marks
                if n > marks.shape[0]:      # the compiled loop writes marks[0..n-1]: never past the array
                    raise ValueError(f"_chunks: {n} chunks recorded at once, at most {marks.shape[0]} (a control period)")
                run_chunks_marked(self._pm, self._pd, n, self.fee_every, self.fee_enabled, kinematics, self._kargs,
                                  self._body_args, self.data.time, self.model.opt.timestep, self._qpos,
                                  self._wheel_qs_arr, marks)
                for k in range(n):
                    self._chunk_hist.append(tuple(marks[k].tolist()))
                return
            run_chunks(self._pm, self._pd, n, self.fee_every, self.fee_enabled, kinematics, self._kargs,
                       self._body_args)
            return
        for _ in range(n):
            self._physics(self.fee_every)
            if record:
                self._chunk_hist.append(self._drift_mark())
        if kinematics:
            mujoco.mj_kinematics(self.model, self.data)

    def _physics(self, n: int) -> None:
        if self.fee_enabled:
            if self.use_kernel:
                self._update_fee()
            else:
                self._update_fee_numpy()
        bucket_body_update(*self._body_args)  # after the FEE update: reads the cut pile and the payload mass
        mujoco.mj_step(self.model, self.data, nstep=n)

    def _anti_windup(self) -> None:
        """A blocked hydraulic joint does not store the commanded motion: at every control
        period the servo's integrated set-point is pulled back to within WINDUP of the
        joint's actual position (a period at full speed leads by at most 0.02 rad)."""
        act, qpos = self._act, self._qpos
        for a, q in ((self.act_boom_adr, self.boom_q), (self.act_bucket_adr, self.bucket_q)):
            act[a] = min(max(act[a], qpos[q] - WINDUP), qpos[q] + WINDUP)

    def _update_fee_numpy(self) -> None:
        """Reference implementation of one FEE update in numpy/python (the kernel must match it)."""
        d, pile = self.data, self.pile
        tip = d.site_xpos[self.sid_tip]
        x, z = float(tip[0]), float(tip[2])
        xmat = d.site_xmat[self.sid_tip]
        pitch = math.atan2(xmat[6], xmat[0])  # x-axis of the tip frame: (xmat[0], xmat[3], xmat[6])
        # cutting: the columns whose centre the tip passed lose the material above the tip
        add_v = add_m = 0.0
        if x >= self._next_center:
            old = pile.top[self._slices].copy()
            m = pile.cut(self._cut_prev_x, self._cut_prev_z, x, z, self._slices)
            self._next_center = (math.floor(x / pile.dx - 0.5) + 1.5) * pile.dx
            if m > 0.0:
                vol = float(np.sum(np.minimum(old, pile.h) - pile.top[self._slices])) * pile.dx * pile.dy
                self.W_ideal += m
                self.V_cut += vol
                add_v, add_m = self.p.loaded_fraction * vol, self.p.loaded_fraction * m
        elif x < self._cut_prev_x:  # moved back: the next centre ahead may be an earlier one
            self._next_center = (math.floor(x / pile.dx - 0.5) + 1.5) * pile.dx
        self._cut_prev_x, self._cut_prev_z = x, z
        # payload: what exceeds the capacity at this pitch spills, at the content's mean density
        if add_v > 0.0 or self._v_bucket > 0.0:
            cap = float(np.interp(pitch, self._cap_pitch, self._cap_vol))
            v, m = self._v_bucket + add_v, self._m_bucket + add_m
            if v > cap:
                spill = m * (v - cap) / v
                self._spilled += spill
                v, m = max(cap, 0.0), m - spill
                add_v = 1.0  # mass changed
            if add_v > 0.0:
                self._v_bucket, self._m_bucket = v, m
                self.model.body_mass[self.bid_bucket] = self.bucket_mass0 + m
        dx_tip, dz_tip = x - self._tip_prev_x, z - self._tip_prev_z
        v_tip = dx_tip / self.fee_dt
        self._tip_prev_x, self._tip_prev_z = x, z
        xfrc = d.xfrc_applied[self.bid_bucket]
        xa = x + 0.5 * pile.dx
        if x < 0.0 or xa >= pile.L or self._n_slices == 0:
            self._no_fee(xfrc)
            return
        rake = min(max(self.rake_attack - pitch, self.rake_lo), self.rake_hi)
        # per slice, the FEE in the frame of the surface ahead of its lip column (fee.py)
        fh, fv, depth, ys, alphas = [], [], [], [], []
        for j in self._slices:
            h_, v_, dn, alpha_s, _ = slice_force(x, z, rake, pile.top[j], pile.x_centers, pile.dx, pile.dz, pile.h,
                                                 pile.n_x, pile.dy, pile.surcharge, pile.adhesion, self.rake_lo,
                                                 pile.density[j], pile.cohesion[j], pile.klass[j], self._phis,
                                                 self._deltas)
            if dn <= 0.0:
                continue
            fh.append(h_)
            fv.append(v_)
            depth.append(dn)
            ys.append(pile.y_centers[j])
            alphas.append(alpha_s)
        if not fh:
            self._no_fee(xfrc)
            return
        fv = np.array(fv)
        # Horizontal: dry friction on the x-tendon (resists motion up to sum F sin(rho_w+delta), no creep).
        mob = 1.0
        if self.fee_by_motion:  # the wedge resists only what pushes it along the face (fee_kernel.wedge_mobilisation)
            mob = wedge_mobilisation(self._mobilised, dx_tip, dz_tip, float(np.mean(alphas)), self.fee_dt,
                                     self.fee_min_speed, self.fee_wedge_tau)
        self._mobilised = mob
        fh_sum = mob * float(np.sum(fh))
        self.model.tendon_frictionloss[self.tid_fee] = fh_sum
        # Vertical: F cos(rho_w+delta) downward, mobilised while the tip advances into the pile.
        ramp = min(max(v_tip / self.fee_min_speed, 0.0), 1.0)
        fz_sum = -ramp * float(fv.sum())
        com = d.xipos[self.bid_bucket]
        # torque about the CoM of the vertical slice forces applied at the tip: r x (0, 0, fz)
        xfrc[:] = 0.0
        xfrc[2] = fz_sum
        xfrc[3] = -ramp * float(np.dot(np.array(ys) - com[1], fv))
        xfrc[4] = -(x - float(com[0])) * fz_sum
        self._fee_h, self._fee_v, self._fee_rake, self._fee_depth = fh_sum, fz_sum, rake, np.array(depth)
        self._alpha_s = float(np.mean(alphas))

    def _update_fee(self) -> None:
        """One FEE update (compiled kernel): cut the pile, set the horizontal resistance on the
        tendon and the vertical force and its torque in xfrc_applied."""
        fee_update(*self._kargs)

    def _bind_kernel(self) -> None:
        """Bind the kernel's arguments once per episode (views into MuJoCo's and the pile's arrays)."""
        m, d, pile = self.model, self.data, self.pile
        st = np.zeros(ST_SIZE)
        st[ST_CUT_X], st[ST_CUT_Z] = self._cut_prev_x, self._cut_prev_z
        st[ST_NEXT_CENTER], st[ST_TIP_PREV_X], st[ST_TIP_PREV_Z] = self._next_center, self._tip_prev_x, self._tip_prev_z
        st[ST_MOBILISED] = self._mobilised
        st[ST_RAKE] = self.rake_attack
        self._kst = st
        par = np.zeros(P_SIZE)
        par[[P_SID_TIP, P_BID_BUCKET, P_TID_FEE]] = self.sid_tip, self.bid_bucket, self.tid_fee
        par[[P_BUCKET_MASS0, P_LOADED_FRACTION, P_FEE_DT, P_FEE_MIN_SPEED]] = (
            self.bucket_mass0, self.p.loaded_fraction, self.fee_dt, self.fee_min_speed)
        par[[P_DX, P_DZ, P_L, P_H, P_W, P_Q, P_CA]] = (
            pile.dx, pile.dz, pile.L, pile.h, pile.dy, pile.surcharge, pile.adhesion)
        par[[P_RAKE_ATTACK, P_RAKE_LO, P_RAKE_HI]] = self.rake_attack, self.rake_lo, self.rake_hi
        par[P_BY_MOTION], par[P_WEDGE_TAU] = self.fee_by_motion, self.fee_wedge_tau
        self._kargs = (d.site_xpos, d.site_xmat, d.xipos, d.xfrc_applied, m.tendon_frictionloss, m.body_mass, st, par,
                       self._slices, pile.top, pile._cum, pile._voxel_mass, pile.density, pile.cohesion, pile.klass,
                       pile.x_centers, pile.y_centers, self._tabs, self._phis, self._deltas, self._cap_pitch,
                       self._cap_vol, self._kdepth, self._kout)

    def _sync_from_kernel(self) -> None:
        st = self._kst
        self.W_ideal = st[ST_W_IDEAL]
        self.pile.removed_mass = st[ST_W_IDEAL]
        self._cut_prev_x, self._cut_prev_z = st[ST_CUT_X], st[ST_CUT_Z]
        self._next_center, self._tip_prev_x, self._tip_prev_z = st[ST_NEXT_CENTER], st[ST_TIP_PREV_X], st[ST_TIP_PREV_Z]
        self._mobilised = st[ST_MOBILISED]
        self._fee_h, self._fee_v, self._fee_rake = st[ST_FH], st[ST_FZ], st[ST_RAKE]
        self._fee_depth = None if st[ST_ENGAGED] else ()   # None: the kernel's depths, read by last_fee
        self.V_cut, self._v_bucket, self._m_bucket = st[ST_V_CUT], st[ST_V_BUCKET], st[ST_M_BUCKET]
        self._spilled, self._alpha_s = st[ST_SPILLED], st[ST_ALPHA_S]

    @property
    def last_fee(self) -> FeeReport:
        xf = self.data.xfrc_applied[self.bid_bucket]
        if self._fee_depth is None:      # engaged at the last sync: the slices' depths (kernel output)
            self._fee_depth = self._kdepth[self._kdepth > 0.0].copy()
        return FeeReport(np.array([-self._fee_h, 0.0, self._fee_v]), xf[3:].copy(), np.asarray(self._fee_depth),
                         math.hypot(self._fee_h, self._fee_v), self._fee_rake, float(self._alpha_s), float(self._mobilised))

    def _no_fee(self, xfrc) -> None:
        if self._fee_h != 0.0 or self._fee_v != 0.0:
            xfrc[:] = 0.0
            self.model.tendon_frictionloss[self.tid_fee] = 0.0
        self._fee_h, self._fee_v, self._fee_depth = 0.0, 0.0, ()
        self._mobilised = 1.0   # the next contact starts with the whole wedge (as the kernel)

    # ------------------------------------------------------------------ readings
    @property
    def loaded_mass(self) -> float:
        """Payload W, the mass in the bucket: loaded_fraction (2/3, paper) of the volume cut from
        the pile, with its per-voxel densities, limited by the bucket's geometric capacity at
        each moment's tip pitch (struck + heap at repose); what exceeds it spilled."""
        return float(self._m_bucket)

    @property
    def spilled_mass(self) -> float:
        """Mass loaded beyond the bucket's capacity and spilled this attempt, kg."""
        return float(self._spilled)

    @property
    def loaded_volume(self) -> float:
        """Volume in the bucket, m^3."""
        return float(self._v_bucket)

    def _drift_mark(self) -> tuple:
        q = self._qpos
        return (self.data.time, float(q[0]), *[float(q[i]) for i in self._wheel_qs])

    def wheel_drift(self) -> tuple[bool, bool]:
        """(front, rear): over the last control period (the window since the mark taken at the
        start of `step`, or at the start of the last n_phys / fee_every chunks of `advance` and of
        the attack drive), a wheel drifts when its rim travel r * dtheta and the machine's travel
        dx differ by more than max(drift_min_speed * T, drift_slip_ratio * the larger of the two):
        the paper compares "the wheel speeds and the total movement of the machine". Travels, not
        the instantaneous joint speeds: a wheel's speed inside a period oscillates with the tyre
        contact (the rear axle's hop when the bucket loads the front), and a sample of it at the
        period's end depends on the integrator's timestep (docs/modeling.md, "Drive and drift")."""
        mark = self._drift_from
        if not mark:
            return False, False
        return self._drift_rule(mark, self._drift_mark())

    def _drift_rule(self, start: tuple, end: tuple) -> tuple[bool, bool]:
        """(front, rear) between two marks (time, x, wheel angles fl, fr, rl, rr): a wheel drifts when its rim
        travel and the machine's travel differ by more than max(drift_min_speed * T, drift_slip_ratio x the larger)."""
        p, r = self.p, self.wheel_radius
        T = end[0] - start[0]
        dx = end[1] - start[1]
        tol_min = p.drift_min_speed * T
        slip = []
        for k in range(len(self._wheel_qs)):
            rim = (end[2 + k] - start[2 + k]) * r
            slip.append(abs(rim - dx) > max(tol_min, p.drift_slip_ratio * max(abs(rim), abs(dx))))
        return slip[0] or slip[1], slip[2] or slip[3]

    def drift_window(self, lag_chunks: int) -> tuple[tuple, tuple] | None:
        """The (start, end) marks (time, x, wheel angles fl, fr, rl, rr) of drift_flag's window: one control period
        ending lag_chunks chunks before now; a start before the history is the first mark's coordinates a period
        before the end (the machine stood); None where the window ends at or before the history's first mark."""
        hist = self._chunk_hist
        if not self._keep_hist:
            raise RuntimeError("drift_flag: no chunk history this episode (conditions.drift_flag_lag_max_s is 0); "
                               "wheel_drift gives the flags of the last control period")
        n = max(1, self.n_phys // self.fee_every)
        if not (isinstance(lag_chunks, (int, np.integer)) and not isinstance(lag_chunks, (bool, np.bool_))
                and 0 <= lag_chunks <= hist.maxlen - n - 1):
            raise ValueError(f"drift_flag: lag_chunks {lag_chunks!r}: expected a whole number of chunks "
                             f"0..{hist.maxlen - n - 1}")
        e = len(hist) - 1 - int(lag_chunks)
        if e <= 0:
            return None
        end = hist[e]
        return (hist[e - n] if e >= n else (end[0] - n * self.fee_dt, *hist[0][1:])), end

    def drift_flag(self, lag_chunks: int) -> tuple[bool, bool]:
        """(front, rear) by wheel_drift's rule over one control period that ends lag_chunks FEE chunks
        before now, from the chunk history (kept while the episode's conditions.drift_flag_lag_max_s > 0):
        the flag as the machine's bridge gives it, whose window ends at its newest camera image, older
        than the instant the policy reads the flag, and so straddles a start from rest where the
        simulator's own window, which begins with the command, does not (docs/modeling.md "A start from
        rest"). Before the history (the machine armed after it stood, or placed before its drive in) the
        machine stood at the history's first mark. lag_chunks 0 gives wheel_drift's flags at the end of every
        step and advance; at the first observation of a start from rest it gives none, where wheel_drift
        covers the last chunks of come_to_rest (a braking wheel may slip there): the machine stood before it
        was armed."""
        window = self.drift_window(lag_chunks)
        if window is None:
            return False, False            # the window ends while the machine stood
        return self._drift_rule(*window)

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

    def wheel_torques(self) -> tuple[float, ...]:
        """(fl, fr, rl, rr) drive torque commanded to each wheel, N m: its motor's speed-servo
        torque, or half the rear motor's where the rear differential splits it."""
        f = self.data.actuator_force
        return tuple(float(f[a]) * share for a, share in self._wheel_torque_from)

    def wheel_speeds(self) -> np.ndarray:
        """(fl, fr, rl, rr) rad/s."""
        return self.data.qvel[self.wheel_dof].copy()
