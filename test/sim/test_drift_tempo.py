"""Drive and drift (issue 13, items 4-5): the drift indicators of a fixed maneuver do not depend
on the integrator's timestep, pushing drifts the rear axle more than the front one, and the drive
force limit is the motors' torque limit over the wheel radius (hand computation below).

Real MuJoCo, the shipped config; expectations computed here from the machine's parameters.
"""
from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from lhd_loading_ros.task.config import load_config
from lhd_sim_node.simulator import AttackError, LhdSimulator

PUSH = np.array([2.7, 0.0, 0.0])   # full wheel speed (paper's 2.7 rad/s), arm still


@pytest.fixture(scope="module")
def cfg():
    return load_config()


def with_timestep(cfg, dt):
    c = copy.deepcopy(cfg)
    c["sim"]["timestep"] = dt
    c["sim"]["fee_every"] = int(round(0.02 / dt))   # the FEE at 50 Hz whatever the timestep
    return c


def push_drift(cfg, slope_deg, steps=60, seed=0):
    """Front and rear drift % of a fixed push-only maneuver: attack at full speed from 0.15 m,
    then `steps` control periods at full wheel speed with the arm still."""
    sim = LhdSimulator(cfg)
    sim.reset(np.random.default_rng(seed), alpha=math.radians(slope_deg), material="homogeneous",
              d_attack=0.15, attack_speed=2.7)
    front = rear = 0
    for _ in range(steps):
        sim.step(PUSH)
        f, r = sim.wheel_drift()
        front += f
        rear += r
    return 100.0 * front / steps, 100.0 * rear / steps


@pytest.mark.parametrize("slope", [20.0, 30.0])
def test_drift_does_not_depend_on_the_timestep(cfg, slope):
    res = {dt: push_drift(with_timestep(cfg, dt), slope) for dt in (0.004, 0.002, 0.001)}
    fronts = [f for f, _ in res.values()]
    rears = [r for _, r in res.values()]
    assert max(fronts) - min(fronts) <= 5.0, res
    assert max(rears) - min(rears) <= 5.0, res


def test_pushing_drifts_the_rear_axle_more_than_the_front(cfg):
    """Paper (real machine, every controller): more rear than front drift. Pushing into the pile
    moves load onto the front axle (payload and the pile's downward pull on the bucket ahead of
    it), so the rear tyres lose grip first."""
    front, rear = push_drift(cfg, 20.0)
    assert rear > front + 20.0, (front, rear)
    assert rear > 50.0, (front, rear)


def static_wheel_loads(sim):
    """Per-wheel normal load (N) of the machine at rest on flat ground, from statics by hand:
    total weight W and the x of the centre of mass (from the bodies' masses and positions);
    moments about the rear axle: N_front_axle = W (x_com - x_rear) / wheelbase."""
    import mujoco
    m, d = sim.model, sim.data
    mujoco.mj_forward(m, d)
    masses = m.body_mass[1:]
    xs = d.xipos[1:, 0]
    W = 9.81 * masses.sum()
    x_com = float((masses * xs).sum() / masses.sum())
    x_rear = float(d.xpos[m.body("wheel_rl").id][0])
    x_front = float(d.xpos[m.body("wheel_fl").id][0])
    n_front_axle = W * (x_com - x_rear) / (x_front - x_rear)
    return n_front_axle / 2, (W - n_front_axle) / 2, W


def test_torque_limit_lies_between_the_rear_and_front_tyre_grip(cfg):
    """The calibration of docs/modeling.md: a motor can spin a rear wheel of the empty machine at
    rest (mu N_rear r < tau) but not a front one (tau < mu N_front r)."""
    sim = LhdSimulator(cfg)
    sim.new_pile(np.random.default_rng(0), alpha=math.radians(20.0), material="homogeneous")
    sim.place_machine(2.0)
    n_front, n_rear, W = static_wheel_loads(sim)
    mc = cfg["machine"]
    mu, r, tau = mc["wheel_friction"], mc["wheel_radius"], mc["wheel_torque_limit"]
    assert abs(W - 9.81 * mc["total_mass"]) < 9.81 * 1.0
    assert mu * n_rear * r < tau < mu * n_front * r, (mu * n_rear * r, tau, mu * n_front * r)


def drive_against(cfg, resistance, seconds=1.5):
    """Machine on flat ground 2 m before the pile (the bucket never reaches it), the FEE off, a fixed
    horizontal resistance on the bucket tip (the fee_x tendon's dry friction); full wheel speed.
    Returns the machine's travel over the last 0.5 s and the mean wheel rim travel over it."""
    sim = LhdSimulator(cfg)
    sim.new_pile(np.random.default_rng(0), alpha=math.radians(20.0), material="homogeneous")
    sim.place_machine(2.0)
    sim.fee_enabled = False
    sim.model.tendon_frictionloss[sim.tid_fee] = resistance
    n = int(round(seconds / sim.p.control_dt))
    for _ in range(n - 5):
        sim.step(PUSH)
    x0, th0 = float(sim.data.qpos[0]), sim.data.qpos[sim._wheel_qs].copy()
    for _ in range(5):
        sim.step(PUSH)
    dx = float(sim.data.qpos[0]) - x0
    rim = (sim.data.qpos[sim._wheel_qs] - th0) * cfg["machine"]["wheel_radius"]
    return dx, rim


def test_drive_force_limit_is_four_torque_limits_over_the_radius(cfg):
    """With tyres that cannot slip (mu = 2), the largest force the drive can push with is
    F = 4 tau / r (tau: each motor's torque limit, r: wheel radius): 4 x 30 / 0.137 = 876 N.
    A resistance 10 % below it is overcome (the machine keeps moving), 10 % above it stalls the
    machine with its wheels at rest (torque-limited: no drift)."""
    c = copy.deepcopy(cfg)
    c["machine"]["wheel_friction"] = 2.0
    mc = c["machine"]
    F = 4 * mc["wheel_torque_limit"] / mc["wheel_radius"]
    dx, _ = drive_against(c, 0.9 * F)
    assert dx > 0.05, dx               # still driving: > 0.1 m/s over the last 0.5 s
    dx, rim = drive_against(c, 1.1 * F)
    assert abs(dx) < 0.005, dx         # stalled
    assert np.all(np.abs(rim) < 0.01), rim   # wheels held by the motors' torque limit, not spinning


def test_attack_timeout_still_raises(cfg):
    c = copy.deepcopy(cfg)
    c["sim"]["attack_timeout"] = 0.2   # the tip cannot travel d_attack + d_init in 0.2 s at 0.37 m/s
    sim = LhdSimulator(c)
    with pytest.raises(AttackError):
        sim.reset(np.random.default_rng(0), alpha=math.radians(20.0), material="homogeneous",
                  d_attack=0.2, attack_speed=2.7)
