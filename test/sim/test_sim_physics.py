"""Physical sanity of the simulator (issue: section 5), on real MuJoCo."""
import math

import numpy as np
import pytest

from lhd_sim_node.env import LhdLoadingEnv
from lhd_sim_node.scripted import push_action, run_episode, scripted_action


@pytest.fixture(scope="module")
def env():
    return LhdLoadingEnv(variant="rld")


def test_model_mass_wheels_and_attack_pose(env):
    m, d = env.sim.model, env.sim.data
    assert float(np.sum(m.body_mass)) == pytest.approx(121.0)
    assert m.geom("wheel_fl").size[0] == pytest.approx(0.137)
    env.sim.new_pile(np.random.default_rng(0), alpha=math.radians(20))
    env.sim.place_machine(0.15)
    tip = d.site_xpos[env.sim.sid_tip]
    assert tip[0] == pytest.approx(-0.15, abs=1e-4)
    assert tip[2] < 0.02  # bucket at ground level
    x_axis = d.site_xmat[env.sim.sid_tip].reshape(3, 3)[:, 0]
    assert abs(x_axis[2]) < 1e-6  # tip frame x-axis parallel to the floor


@pytest.mark.parametrize("slope", [15.0, 20.0, 30.0])
def test_pushing_without_lifting_ends_stuck_or_drifting(env, slope):
    res = run_episode(env, push_action, seed=11, options={"slope_deg": slope, "material": "homogeneous"})
    assert not res.reached_end_zone
    assert res.truncated  # 20 s against the face
    assert max(res.front_drift_pct, res.rear_drift_pct) > 50.0
    s = env.state
    assert abs(s.v_x) < 0.02  # stalled


@pytest.mark.parametrize("slope", [15.0, 20.0])
def test_scripted_maneuver_loads(env, slope):
    """Drive in; lift and curl past x_midgoal, or earlier when the wheels drift (the dense ore
    can stall the machine before x_midgoal)."""
    for seed in range(3):
        res = run_episode(env, lambda s: scripted_action(s, env.p.x_midgoal, lift_on_drift=True), seed=seed,
                          options={"slope_deg": slope, "material": "homogeneous"})
        assert res.reached_end_zone, seed
        assert res.loaded >= 20.0
        assert res.success_level >= 1


def test_pile_force_acts_on_the_bucket_and_payload_adds_mass(env):
    env.reset(seed=5, options={"slope_deg": 25.0, "material": "homogeneous"})
    sim = env.sim
    for _ in range(4):
        env.step(np.array([1.0, 1.0, -1.0]))
    fee = sim.last_fee
    assert fee.magnitude > 100.0 and len(fee.depth) == sim.pile.n_y
    assert sim.model.tendon_frictionloss[sim.tid_fee] == pytest.approx(-fee.force[0])
    assert sim.model.body_mass[sim.bid_bucket] == pytest.approx(sim.bucket_mass0 + sim.loaded_mass)
    assert sim.loaded_mass == pytest.approx(min(2.0 / 3.0 * sim.pile.removed_mass, 37.5))
    # the vertical component goes through xfrc_applied, with its torque about the bucket CoM
    xf = sim.data.xfrc_applied[sim.bid_bucket]
    com = sim.data.xipos[sim.bid_bucket]
    assert xf[4] == pytest.approx(-(env.state.x_shovel - com[0]) * xf[2], rel=0.05, abs=1.0)


def test_resistance_grows_with_slope(env):
    """At the same penetration the pile stops the machine earlier when it is steeper."""
    stall = []
    for slope in (15.0, 22.0, 30.0):
        run_episode(env, push_action, seed=21, options={"slope_deg": slope, "material": "homogeneous",
                                                         "attack_speed": 2.7, "d_attack": 0.15})
        stall.append(env.state.x_shovel)
    assert stall[0] > stall[1] > stall[2]


def test_drift_detection_per_axle(env):
    env.reset(seed=6, options={"slope_deg": 20.0})
    sim = env.sim
    d = sim.data
    q = sim._wheel_qs
    # drift is judged on travel over the control period (wheel_drift): 0.1 s at 0.2 m/s
    sim._drift_from = sim._drift_mark()
    d.time += 0.1
    d.qpos[0] += 0.02
    d.qpos[q] += 0.02 / 0.137
    assert sim.wheel_drift() == (False, False)
    d.qpos[q[2]] += 0.27 - 0.02 / 0.137  # rear left turned 2.7 rad/s while the machine moved 0.2 m/s
    assert sim.wheel_drift() == (False, True)
    d.qpos[q[0]] -= 0.02 / 0.137  # front left locked: skids
    assert sim.wheel_drift() == (True, True)


def test_compiled_kernel_matches_numpy_reference():
    """The numba FEE/cutting kernel and the numpy reference give the same episode."""
    outs = []
    for use_kernel in (True, False):
        e = LhdLoadingEnv(variant="rld")
        e.sim.use_kernel = use_kernel
        res = run_episode(e, lambda s: scripted_action(s, e.p.x_midgoal), seed=3,
                          options={"slope_deg": 22.0, "material": "nonhomogeneous"})
        outs.append((res.loaded, res.steps, e.state.x_shovel, e.state.z_shovel, e.sim.pile.total_mass()))
    np.testing.assert_allclose(outs[0], outs[1], rtol=1e-6)


def test_first_episode_equals_a_later_one_with_the_same_seed():
    e = LhdLoadingEnv(variant="rld")
    runs = [run_episode(e, lambda s: scripted_action(s, e.p.x_midgoal), seed=9,
                        options={"slope_deg": 18.0, "material": "homogeneous"}) for _ in range(2)]
    assert runs[0].loaded == runs[1].loaded > 0 and runs[0].steps == runs[1].steps


def test_payload_is_bounded_by_the_bucket_geometry_and_nothing_is_lost(env):
    """A scripted attempt on a steep pile: the bucket holds at most its heaped volume at its final
    pitch (struck + heap at the angle of repose, times the fill factor's scale, task/bucket_capacity.py),
    what it loaded plus what spilled is 2/3 of the mass cut from the pile (the paper's loaded fraction),
    and the bucket body carries exactly the payload. No mass cap."""
    from lhd_loading_ros.task.bucket_capacity import fill_scale, heaped_volume

    run_episode(env, lambda s: scripted_action(s, env.p.x_midgoal, lift_on_drift=True), seed=12,
                options={"slope_deg": 30.0, "material": "homogeneous"})
    sim = env.sim
    cfg = env.cfg
    pitch = sim.state().phi_shovel
    cap = heaped_volume(pitch, cfg["machine"], math.radians(cfg["task"]["bucket_repose_deg"])) * fill_scale(cfg)
    assert sim.loaded_volume <= cap * (1 + 1e-6) + 1e-9
    assert sim.loaded_mass + sim.spilled_mass == pytest.approx(2.0 / 3.0 * sim.pile.removed_mass, rel=1e-6)
    assert sim.model.body_mass[sim.bid_bucket] == pytest.approx(sim.bucket_mass0 + sim.loaded_mass)
