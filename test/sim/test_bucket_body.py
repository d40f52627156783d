"""The whole bucket in the pile (issue 13, item 2): breakout of the material over the opening and
ploughing of the heel, on real MuJoCo.

The expectations are hand calculations written here from textbook soil mechanics on the intact
wedge pile (surface z = x tan(alpha)) and the bucket's measured pose: the block of material over
the bottom plate must be lifted and sheared free on vertical planes (Meyerhof & Adams 1968:
tau = c + K_u sigma_v tan(phi), sigma_v = gamma z), and a heel below the lip's cut meets
Rankine's passive pressure. They never call the simulator's bucket_body formulas.
"""
import math

import mujoco
import numpy as np
import pytest

from lhd_loading_ros.task.config import ConfigError, load_config, validate
from lhd_loading_ros.task.kinematics import PLATE_T
from lhd_sim_node.bucket_body import O_NAMES, body_forces_reference, bucket_body_update
from lhd_sim_node.simulator import LhdSimulator

G = 9.81
D_IN = 0.25  # m, the lip pushed this far into the pile


@pytest.fixture(scope="module")
def sim():
    return LhdSimulator(load_config())


def _new(sim, alpha_deg, seed=0):
    sim.fee_enabled = True
    sim.new_pile(np.random.default_rng(seed), alpha=math.radians(alpha_deg), material="homogeneous")


def _bury(sim, alpha_deg, d_in=D_IN):
    """Drive the machine (arm still) until the lip is d_in inside an intact pile; come to rest."""
    _new(sim, alpha_deg)
    sim.place_machine(0.15)
    sim.set_command(np.array([sim.p.wheels_max, 0.0, 0.0]))
    while sim.data.site_xpos[sim.sid_tip][0] < d_in:
        sim._physics(sim.fee_every)
    for _ in range(5):
        sim.step(np.zeros(3))


def _fee_off(sim):
    """Isolate the bucket body: no lip FEE (its tendon and force zeroed), no further cutting."""
    sim.fee_enabled = False
    sim.model.tendon_frictionloss[sim.tid_fee] = 0.0
    sim.data.xfrc_applied[:] = 0.0


def _pose(sim):
    d = sim.data
    joint = d.xpos[sim.bid_bucket][[0, 2]].copy()
    tip = d.site_xpos[sim.sid_tip][[0, 2]].copy()
    heel = d.site_xpos[sim.sid_bottom][[0, 2]].copy() + np.array([0.0, PLATE_T])  # plate top at the heel
    return joint, tip, heel


def hand_breakout(sim, alpha_deg):
    """Breakout of the block over the bucket's plate in an intact wedge pile (hand calculation).

    Block: between the plate's top surface and the pile surface z = x tan(alpha), over the plate,
    across the bucket's width w. Its weight beyond the payload (whose weight the bucket already
    carries) must be lifted; its two side planes (soil on the side walls' outside below their top
    edge, soil on soil above) and the front plane through the lip (soil on soil) sheared, with
    tau = c + K_u gamma z tan(phi or delta). Curl: each force times its lever about the bucket
    joint (weight: horizontal lever of the block's centroid; vertical front shear: horizontal
    lever of the lip; side shear: distance of each strip's mid-height from the joint)."""
    pile, mc, bb = sim.pile, sim.cfg["machine"], sim.cfg["bucket_body"]
    ta = math.tan(math.radians(alpha_deg))
    rho, c = float(pile.density.mean()), float(pile.cohesion.mean())
    tphi, tdel = math.tan(float(pile.phi.mean())), math.tan(float(pile.delta.mean()))
    K, w, wall = bb["k_uplift"], mc["bucket_width"], mc["bucket_back_height"] / 2
    kg = K * rho * G
    (xj, zj), (xt, zt), (xe, ze) = _pose(sim)
    surf = lambda x: np.clip(x * ta, 0.0, pile.h)  # noqa: E731
    n = 2000
    x = xe + (np.arange(n) + 0.5) * (xt - xe) / n
    dxq = (xt - xe) / n
    zp = ze + (x - xe) * (zt - ze) / (xt - xe)
    H = np.maximum(surf(x) - zp, 0.0)
    m_over = rho * w * float(H.sum()) * dxq
    payload = sim.loaded_mass
    w_ob = G * max(m_over - payload, 0.0)
    xbar = float((H * x).sum() / H.sum()) if H.sum() > 0 else xj
    d1 = np.clip(surf(x) - (zp + wall), 0.0, H)  # depth of soil-on-soil above the side walls' top edge
    tau_int = c * d1 + 0.5 * kg * tphi * d1 ** 2 + 0.5 * kg * tdel * (H ** 2 - d1 ** 2)  # per metre of plane
    s_side = 2.0 * float(tau_int.sum()) * dxq
    t_side = 2.0 * float((tau_int * np.hypot(x - xj, 0.5 * (zp + surf(x)) - zj)).sum()) * dxq
    hf = max(float(surf(xt)) - zt, 0.0)
    s_front = w * (c * hf + 0.5 * kg * tphi * hf ** 2)
    lift = w_ob + s_side + s_front
    curl = w_ob * max(xbar - xj, 0.0) + t_side + s_front * max(xt - xj, 0.0)
    return {"lift": lift, "curl": curl, "w_ob": w_ob, "s_side": s_side, "s_front": s_front, "h_front": hf}


def _servo_torque(sim, u, act, n, hand=None):
    """Servo torque after each of n control steps with command u (and the hand calculation of
    the resistance at each step's pose, when given a function of the simulator)."""
    out, ref = [], []
    for _ in range(n):
        sim.step(u)
        out.append(float(sim.data.actuator_force[act]))
        ref.append(hand(sim) if hand else 0.0)
    return np.array(out), np.array(ref)


def _in_air_like(sim, alpha_deg, bucket_mass):
    """The same machine far before the toe, its bucket as heavy as the loaded one."""
    _new(sim, alpha_deg)
    sim.place_machine(0.8)
    sim.model.body_mass[sim.bid_bucket] = bucket_mass
    for _ in range(5):
        sim.step(np.zeros(3))


@pytest.mark.parametrize("alpha_deg", [20.0, 30.0])
def test_breakout_of_a_buried_bucket_matches_the_hand_calculation(sim, alpha_deg):
    """Lip 0.25 m into 20 and 30 deg piles: the limits the simulator sets and the servo torques
    measured by curling and lifting slowly (the same motions in air with an equally heavy bucket
    subtracted) agree with the hand calculation within +-30 %."""
    _bury(sim, alpha_deg)
    _fee_off(sim)
    hand = hand_breakout(sim, alpha_deg)
    rep = sim.body.report()
    assert hand["lift"] > 30.0 and hand["curl"] > 5.0, hand
    assert rep["lift"] == pytest.approx(hand["lift"], rel=0.3), (rep, hand)
    assert rep["curl"] == pytest.approx(hand["curl"], rel=0.3), (rep, hand)
    mass = float(sim.model.body_mass[sim.bid_bucket])
    state = (sim.data.qpos.copy(), sim.data.qvel.copy(), sim.data.act.copy(), sim.pile.top.copy(), sim.body.ob.copy())
    # curl at 0.02 rad/s (quasi-static): bucket servo torque, buried minus in air; the hand
    # calculation at the pose of each step (the block thins as the plate rises)
    u_curl = np.array([0.0, 0.0, 0.02])
    buried, hand_curl = _servo_torque(sim, u_curl, sim.act_bucket, 6, lambda s: hand_breakout(s, alpha_deg)["curl"])
    # lift at 0.01 rad/s: boom servo torque; the vertical limit acts at the bucket joint
    sim.data.qpos[:], sim.data.qvel[:], sim.data.act[:] = state[0], state[1], state[2]
    sim.pile.top[:] = state[3]
    sim.body.ob[:] = state[4]
    mujoco.mj_forward(sim.model, sim.data)
    lever = float(sim.data.xpos[sim.bid_bucket][0] - sim.data.xpos[sim.model.body("boom").id][0])
    u_lift = np.array([0.0, -0.01, 0.0])
    buried_lift, hand_lift = _servo_torque(sim, u_lift, sim.act_boom, 6, lambda s: hand_breakout(s, alpha_deg)["lift"])
    _in_air_like(sim, alpha_deg, mass)
    assert sim.body.report()["lift"] == 0.0 and sim.body.report()["curl"] == 0.0
    air, _ = _servo_torque(sim, u_curl, sim.act_bucket, 6)
    _in_air_like(sim, alpha_deg, mass)
    air_lift, _ = _servo_torque(sim, u_lift, sim.act_boom, 6)
    # the first two steps build the servo's torque up to breakaway; average over the rest
    t_curl = float(np.mean(buried[2:] - air[2:]))
    f_lift = float(np.mean(-(buried_lift[2:] - air_lift[2:]))) / lever
    assert t_curl == pytest.approx(float(np.mean(hand_curl[2:])), rel=0.3), (t_curl, hand_curl)
    assert f_lift == pytest.approx(float(np.mean(hand_lift[2:])), rel=0.3), (f_lift, hand_lift)


def test_curl_resistance_does_not_vanish_while_the_lip_is_below_the_face(sim):
    """Full simulator (lip FEE on): curl a bucket buried 0.25 m in a 25 deg pile at full speed
    through its whole range. While the lip is more than 1 cm below the intact face ahead of it,
    the curl resistance is at least 70 % of the front plane's shear alone (hand calculation:
    w (c h + 1/2 K_u gamma h^2 tan phi) times the lip's lever)."""
    alpha = 25.0
    _bury(sim, alpha)
    pile = sim.pile
    ta = math.tan(math.radians(alpha))
    rho, c, tphi = float(pile.density.mean()), float(pile.cohesion.mean()), math.tan(float(pile.phi.mean()))
    K, w = sim.cfg["bucket_body"]["k_uplift"], sim.cfg["machine"]["bucket_width"]
    below = 0
    for _ in range(80):
        sim.step(np.array([0.0, 0.0, sim.p.bucket_max]))
        (xj, _), (xt, zt), _ = _pose(sim)
        h = xt * ta - zt  # lip below the intact face
        if h > 0.01:
            below += 1
            front = w * (c * h + 0.5 * K * rho * G * h * h * tphi) * max(xt - xj, 0.0)
            assert sim.body.report()["curl"] >= 0.7 * front > 0.0, (sim.state().phi_bucket, h)
            assert sim.model.dof_frictionloss[sim.body.dof] == sim.body.report()["curl"]
    assert below >= 10  # the lip stayed under the face for a good part of the curl


def test_a_bucket_in_air_feels_nothing(sim):
    _new(sim, 20.0)
    sim.place_machine(0.6)
    for u in ([0.0, 0.0, 0.2], [0.0, -0.19, 0.0], [2.0, -0.1, 0.1]):
        for _ in range(5):
            sim.step(np.array(u))
            assert all(v == 0.0 for v in sim.body.report().values())
            assert sim.model.dof_frictionloss[sim.body.dof] == 0.0
            assert sim.model.tendon_frictionloss[sim.body.tid_z] == 0.0
            assert sim.model.tendon_frictionloss[sim.body.tid_x] == 0.0


def test_the_heel_ploughs_below_the_lips_cut(sim):
    """Curl a buried bucket by 0.25 rad and drive on with the arm still: the lip now cuts a floor
    at its own height, and once the heel reaches that floor it ploughs below it, meeting
    Rankine's passive pressure on its depth h: w (1/2 gamma h^2 K_p + 2 c h sqrt(K_p))."""
    _bury(sim, 20.0, d_in=0.2)
    while sim.state().phi_bucket < 0.25:
        sim.step(np.array([0.0, 0.0, sim.p.bucket_max]))
    _, (xt0, zt0), _ = _pose(sim)
    pile = sim.pile
    sp = math.sin(float(pile.phi.mean()))
    kp = (1 + sp) / (1 - sp)
    rho, c = float(pile.density.mean()), float(pile.cohesion.mean())
    plough = []
    for _ in range(40):
        sim.step(np.array([sim.p.wheels_max, 0.0, 0.0]))
        _, _, (xe, ze) = _pose(sim)
        if xe > xt0 + 2 * pile.dx:  # the heel is over the floor the curled lip cut
            h = zt0 - ze
            hand = sim.cfg["machine"]["bucket_width"] * (0.5 * rho * G * h * h * kp + 2 * c * h * math.sqrt(kp))
            plough.append((sim.body.report()["plough"], hand))
            assert sim.model.tendon_frictionloss[sim.body.tid_x] == sim.body.report()["plough"]
    assert len(plough) >= 3
    got, hand = np.array(plough).T
    assert np.all(hand > 20.0)
    assert got.mean() == pytest.approx(hand.mean(), rel=0.3)


def test_no_resistance_does_positive_work(sim):
    """Push, curl and lift a buried bucket with the full simulator. The bucket body's dry friction
    (bucket joint, body_z and body_x tendons) dissipates: the work of its constraint forces
    (force times constraint velocity, summed over the three rows) is negative, and the positive
    work of MuJoCo's soft friction in its stick phase (the solver's regularisation, while other
    forces brake or reverse the motion) stays under 2 % of the dissipated work. The kernel never
    writes xfrc_applied (the lip FEE's row stays the FEE's)."""
    _bury(sim, 25.0)
    m, d = sim.model, sim.data
    fd, ft = int(mujoco.mjtConstraint.mjCNSTR_FRICTION_DOF), int(mujoco.mjtConstraint.mjCNSTR_FRICTION_TENDON)
    ours = {(fd, sim.body.dof), (ft, sim.body.tid_z), (ft, sim.body.tid_x)}
    pos = neg = 0.0
    plan = [[2.7, 0.0, 0.2]] * 10 + [[1.0, -0.19, 0.0]] * 10 + [[0.0, 0.0, 0.2]] * 5 + [[2.7, -0.19, 0.2]] * 10
    for u in plan + [[0.0, 0.0, 0.0]] * 5:
        sim.set_command(np.array(u))
        sim._anti_windup()
        for k in range(sim.n_phys):
            if k % sim.fee_every == 0:
                xf = d.xfrc_applied.copy()
                bucket_body_update(*sim._body_args)
                assert np.array_equal(d.xfrc_applied, xf)
            sim._physics(1) if k % sim.fee_every == 0 else mujoco.mj_step(m, d)
            p = sum(d.efc_force[r] * d.efc_vel[r] for r in range(d.nefc)
                    if (int(d.efc_type[r]), int(d.efc_id[r])) in ours)
            pos, neg = pos + max(p, 0.0) * m.opt.timestep, neg + min(p, 0.0) * m.opt.timestep
    assert neg < -10.0  # J dissipated: the body resisted
    assert pos < 0.02 * -neg, (pos, neg)


def test_a_buried_bucket_at_rest_stays_at_rest(sim):
    """Nothing pushes: with all commands at zero the buried bucket and the machine do not move."""
    _bury(sim, 30.0, d_in=0.3)
    for _ in range(5):
        sim.step(np.array([0.0, 0.0, 0.2]))  # leave it curled a little, the body's limits all engaged
    assert sim.body.report()["curl"] > 0.0 and sim.body.report()["lift"] > 0.0
    tip0 = sim.data.site_xpos[sim.sid_tip].copy()
    for _ in range(10):
        sim.step(np.zeros(3))
    assert np.linalg.norm(sim.data.site_xpos[sim.sid_tip] - tip0) < 2e-3
    assert abs(sim.data.qvel[sim.bucket_v]) < 1e-3 and abs(sim.data.qvel[sim.boom_v]) < 1e-3


def test_kernel_matches_the_numpy_reference(sim):
    _bury(sim, 25.0, d_in=0.35)
    for _ in range(6):  # curl and lift a little, driving on: a pose with every term at work
        sim.step(np.array([1.5, -0.1, 0.2]))
    d, b = sim.data, sim.body
    R = d.xmat[sim.bid_bucket].reshape(3, 3)
    payload = float(sim.model.body_mass[sim.bid_bucket]) - sim.bucket_mass0
    ref = body_forces_reference(d.xpos[sim.bid_bucket][[0, 2]], ((R[0, 0], R[0, 2]), (R[2, 0], R[2, 2])),
                                max(payload, 0.0), b.par, b.slices, sim.pile, b.ob)
    bucket_body_update(*sim._body_args)
    got = b.report()
    assert got["lift"] > 0.0 and got["curl"] > 0.0
    for name in O_NAMES:
        assert got[name] == pytest.approx(ref[name], rel=1e-9, abs=1e-9), name


def test_config_section_is_validated():
    cfg = load_config()
    cfg["bucket_body"]["k_uplift"] = -1.0
    with pytest.raises(ConfigError, match="k_uplift"):
        validate(cfg)
    cfg = load_config()
    del cfg["bucket_body"]["enabled"]
    with pytest.raises(ConfigError, match="enabled"):
        validate(cfg)
