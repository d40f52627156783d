"""The ten reward terms of the paper (Eq. r_total and Table "Reward's components summary").

Each term is a pure function of the quantities named in its equation; constants come from
TaskParams (config/lhd_params.yaml). Angles in radians except where the paper's constants
are in degrees (the pitch distance of r_success is taken in degrees, like rho_thresh^phi).
:class:`RewardTracker` keeps the little history two terms need (previous tip position for
r_traj, the last T_stuck+1 displacements for r_stuck) and sums the terms for one step.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field, replace

from lhd_loading_ros.task.metrics import SL_BANDS, success_level
from lhd_loading_ros.task.params import TaskParams
from lhd_loading_ros.task.state import LhdState
from lhd_loading_ros.task.zones import Zones

TERMS = ("traj", "midgoal", "inact", "drift", "stuck", "dump", "bottom", "weight", "success", "zone")


# ------------------------------------------------------------------ r_traj
def z_rail(x: float, x_max: float, p: TaskParams) -> float:
    """Eq. rail: z_rail = (x + x_delta + (x_offset - x_max))^17 - z_offset."""
    return (x + p.x_delta + (p.x_offset - x_max)) ** p.rail_exponent - p.z_offset


def traj_angles(x: float, z: float, x_prev: float, z_prev: float, zones: Zones, h_pile: float,
                p: TaskParams) -> tuple[float, float, float]:
    """(alpha_shovel, alpha_lower, alpha_upper) in the XZ plane.

    alpha_shovel: direction of the tip's displacement from t-1 to t. Upper bound: the vector
    from the tip to (x_min, z_upper), z_upper = h_pile/2 before x_min, z_min after. Lower
    bound: the vector from the tip to (x + x_delta, z_rail). The paper refers the vectors to
    the bucket tip frame; rotating all three by the same pitch does not change how they
    compare, so they are compared in {M}.
    """
    a_shovel = math.atan2(z - z_prev, x - x_prev)
    z_upper = h_pile / 2.0 if x < zones.x_min else zones.z_min
    a_upper = math.atan2(z_upper - z, zones.x_min - x)
    a_lower = math.atan2(z_rail(x, zones.x_max, p) - z, p.x_delta)
    return a_shovel, a_lower, a_upper


def r_traj(a_shovel: float, a_lower: float, a_upper: float, inside_pile: bool, p: TaskParams) -> float:
    """-R_traj if the tip's direction leaves [alpha_lower, alpha_upper] while inside the pile."""
    if not inside_pile:
        return 0.0
    return -p.R_traj if (a_shovel < a_lower or a_shovel > a_upper) else 0.0


# ------------------------------------------------------------------ per-step terms
def r_midgoal(x: float, p: TaskParams) -> float:
    """-R_midgoal * |x - x_midgoal| / d_midgoal_max while x < x_midgoal."""
    if x >= p.x_midgoal:
        return 0.0
    return -p.R_midgoal * abs(x - p.x_midgoal) / p.d_midgoal_max


def r_inact(u_boom: float, u_bucket: float, x: float, p: TaskParams) -> float:
    """-R_inact if (|u_boom / boom_min| < u_thresh_boom or |u_bucket / bucket_max| < u_thresh_bucket)
    once x >= x_midgoal."""
    if x < p.x_midgoal:
        return 0.0
    weak = abs(u_boom / p.boom_min) < p.u_thresh_boom or abs(u_bucket / p.bucket_max) < p.u_thresh_bucket
    return -p.R_inact if weak else 0.0


def r_drift(drift: bool, u_boom: float, u_bucket: float, p: TaskParams) -> float:
    """-R_drift * I_drift if neither the boom nor the bucket moves (u == 0)."""
    still = abs(u_boom) < 1e-12 and abs(u_bucket) < 1e-12
    return -p.R_drift if (drift and still) else 0.0


def r_stuck(recent_dx, p: TaskParams) -> float:
    """-R_stuck if the tip moved less than delta_thresh along x in each of the last
    T_stuck + 1 steps (Delta^t ... Delta^{t-T_stuck})."""
    if len(recent_dx) < p.T_stuck + 1:
        return 0.0
    return -p.R_stuck if all(abs(d) < p.delta_thresh for d in list(recent_dx)[-(p.T_stuck + 1):]) else 0.0


def r_dump(phi_shovel: float, p: TaskParams) -> float:
    """-R_dump if r_dump_sign * phi_shovel >= phi_thresh^pitch. r_dump_sign = -1 (default):
    the bucket tilted forward by phi_thresh or more, where material falls out (the paper's
    prose); +1: the printed inequality, which with phi_shovel > phi_thresh required for
    success penalises the very pose success asks for (docs/modeling.md, docs/training.md)."""
    return -p.R_dump if p.r_dump_sign * phi_shovel >= p.phi_thresh_pitch else 0.0


def r_bottom(z_bottom: float, z_pile_at_bottom: float, p: TaskParams) -> float:
    """-R_bottom if the bucket bottom B is buried: z_bottom <= z_pile(x_bottom) (less a
    small tolerance for the heel riding on the floor of its own cut)."""
    return -p.R_bottom if z_bottom <= z_pile_at_bottom - p.bottom_tolerance else 0.0


def r_weight(W: float, p: TaskParams, W_prev: float = 0.0) -> float:
    """Paper: R_weight * W^t (kg in the bucket), every step. With r_weight_increments = 1
    (default): R_weight * (W^t - W^{t-1}), the material as it enters the bucket; an episode
    sums to R_weight * (W^T - W^0), W^0 being what the attack drive scooped before the first step
    (0.07-0.9 kg), and holding a full bucket earns nothing (docs/training.md)."""
    return p.R_weight * (W - W_prev) if p.r_weight_increments else p.R_weight * W


# ------------------------------------------------------------------ terminal terms
def delta_small(x: float, target: float, rho_thresh: float) -> float:
    """delta(x, x_target) of Eq. eucli_single, as a non-negative distance:
    (rho + ln rho) - (rho_thresh + ln rho_thresh) with rho = max(rho_thresh, |x - target|).
    The paper prints it with the opposite sign, which would make Delta divide by
    max delta = 0; the magnitude is what Delta in [0, 1] needs."""
    rho = max(rho_thresh, abs(x - target))
    return (rho + math.log(rho)) - (rho_thresh + math.log(rho_thresh))


def delta_big(x: float, target: float, rho_thresh: float, max_distance: float) -> float:
    """Delta(x, x_target) = 1 - delta / max delta, in [0, 1]: 1 within rho_thresh of the
    target, 0 at the largest possible distance max_distance."""
    dmax = delta_small(target + max_distance, target, rho_thresh)
    if dmax <= 0.0:
        return 1.0
    return min(1.0, max(0.0, 1.0 - delta_small(x, target, rho_thresh) / dmax))


def success_deltas(W: float, phi: float, p: TaskParams) -> tuple[float, float]:
    """(Delta_weight, Delta_pitch). Weight distances in kg (largest: an empty bucket, W_target);
    pitch distances in degrees (largest: the far end of the pitch range)."""
    d_w = delta_big(W, p.W_target, p.rho_thresh_W, p.W_target)
    deg = math.degrees
    max_phi = max(abs(deg(p.phi_shovel_min - p.phi_target)), abs(deg(p.phi_shovel_max - p.phi_target)))
    d_p = delta_big(deg(phi), deg(p.phi_target), deg(p.rho_thresh_phi), max_phi)
    return d_w, d_p


def r_success(W: float, phi: float, p: TaskParams) -> float:
    """R_success * (Delta_weight + Delta_pitch) / 2 * max(W^T, W_target), paid when the tip
    reaches the end zone; with r_success_requires_sl (default) only if the attempt also meets
    the paper's success test, SL >= 1 (W^T >= 20 kg, phi^T > phi_thresh), with the pitch test
    raised by the training margin r_success_pitch_margin and the mass test by r_success_mass_margin
    (the episode's own success test is not)."""
    if p.r_success_requires_sl and (success_level(W, phi, p.phi_thresh_pitch + p.r_success_pitch_margin) < 1
                                    or W < SL_BANDS[-1][0] + p.r_success_mass_margin):
        return 0.0
    d_w, d_p = success_deltas(W, phi, p)
    return p.R_success * (d_w + d_p) / 2.0 * max(W, p.W_target)


def r_success_margin_cut(W: float, phi: float, p: TaskParams) -> float:
    """What the training margins (r_success_pitch_margin, r_success_mass_margin) take away from
    r_success (<= 0): r_success with the margins minus r_success at the paper's success test.
    Nonzero only for a final pitch within the pitch margin above phi_thresh or a load within the
    mass margin above 20 kg. Training keeps it apart when the margins are ramped in
    (learning/ddpg.TiltRamp)."""
    if p.r_success_pitch_margin == 0.0 and p.r_success_mass_margin == 0.0:
        return 0.0
    return r_success(W, phi, p) - r_success(W, phi, replace(p, r_success_pitch_margin=0.0, r_success_mass_margin=0.0))


def r_zone(restricted: bool, p: TaskParams) -> float:
    """-R_zone when the tip enters the restricted zone (terminal failure)."""
    return -p.R_zone if restricted else 0.0


def r_tilt(machine_pitch: float, p: TaskParams) -> float:
    """Not in the paper (task.r_tilt_per_deg, a training-only setting; 0 = off): a cost for tipping
    the machine, -r_tilt_per_deg per degree of the rear frame's |pitch| beyond r_tilt_free_deg, at
    each control period's end. The paper's reward has no term for it, and actors trained on it
    learned to pry the rear off the floor with the boom on steep piles (up to 28 deg in the
    simulator; docs/real_machine.md), which the real machine's supervisor must then stop."""
    excess = math.degrees(abs(machine_pitch) - p.r_tilt_free)
    return -p.r_tilt_per_deg * excess if excess > 0.0 else 0.0


# ------------------------------------------------------------------ one step
@dataclass
class RewardTracker:
    p: TaskParams
    zones: Zones
    h_pile: float
    x_prev: float = 0.0
    z_prev: float = 0.0
    W_prev: float = 0.0
    recent_dx: deque = field(default_factory=deque)
    margin_cut: float = 0.0        # the last step's r_success_margin_cut (in terms["success"] already)

    def reset(self, s: LhdState, W0: float = 0.0) -> None:
        """W0: what the bucket already holds when the episode starts (cut during the attack)."""
        self.x_prev, self.z_prev = s.x_shovel, s.z_shovel
        self.W_prev = W0
        self.recent_dx = deque(maxlen=self.p.T_stuck + 1)

    def step(self, s: LhdState, u_boom: float, u_bucket: float, W: float, inside_pile: bool,
             z_pile_at_bottom: float, outcome: str, machine_pitch: float = 0.0) -> dict[str, float]:
        """Reward terms for the transition into state s. outcome: 'success', 'failure' or 'running'.
        machine_pitch: the rear frame's pitch (rad) for r_tilt, a term only while it is on."""
        p = self.p
        self.recent_dx.append(s.x_shovel - self.x_prev)
        a_s, a_lo, a_up = traj_angles(s.x_shovel, s.z_shovel, self.x_prev, self.z_prev, self.zones, self.h_pile, p)
        terms = {
            "traj": r_traj(a_s, a_lo, a_up, inside_pile, p),
            "midgoal": r_midgoal(s.x_shovel, p),
            "inact": r_inact(u_boom, u_bucket, s.x_shovel, p),
            "drift": r_drift(s.drift, u_boom, u_bucket, p),
            "stuck": r_stuck(self.recent_dx, p),
            "dump": r_dump(s.phi_shovel, p),
            "bottom": r_bottom(s.z_bottom, z_pile_at_bottom, p),
            "weight": r_weight(W, p, self.W_prev),
            "success": r_success(W, s.phi_shovel, p) if outcome == "success" else 0.0,
            "zone": r_zone(outcome == "failure", p),
        }
        if p.r_tilt_per_deg > 0.0:
            terms["tilt"] = r_tilt(machine_pitch, p)
        self.margin_cut = r_success_margin_cut(W, s.phi_shovel, p) if outcome == "success" else 0.0
        self.x_prev, self.z_prev = s.x_shovel, s.z_shovel
        self.W_prev = W
        return terms
