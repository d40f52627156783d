"""The policy node's ROS-free core: forward kinematics against MuJoCo, the observation from
measurements against the environment's, and the zero command on every kind of doubt."""
import math

import numpy as np
import pytest

from lhd_loading_ros.task.actions import rlc_deploy_filter, to_actuator
from lhd_loading_ros.task.kinematics import ArmKinematics, quat_to_mat, state_from_measurements
from lhd_loading_ros.policy.core import ZERO_COMMAND, Inputs, PolicyCore
from lhd_sim_node.env import LhdLoadingEnv

FK_ATOL = 1e-9   # m / rad: forward kinematics vs MuJoCo's site poses


def measurements(env):
    d = env.sim.data
    s = env.state
    art = 0.0   # the articulation is rigid in the model (mjcf.py): its encoder would read 0
    joints = {"boom": (s.phi_boom, s.dphi_boom), "bucket": (s.phi_bucket, s.dphi_bucket), "articulation": (art, 0.0)}
    return tuple(d.qpos[:3]), tuple(d.qpos[3:7]), s.v_x, joints, s.drift_front, s.drift_rear


def feed(inp, env, now):
    pos, quat, v, joints, f, r = measurements(env)
    inp.put("joints", joints, now)
    inp.put("odom", (pos, quat, v), now)
    inp.put("drift_front", f, now)
    inp.put("drift_rear", r, now)
    inp.put("slope", env.sim.pile.alpha, now)
    z = env.sim.zones
    inp.put("end_zone", (z.x_min, z.x_max, z.z_min), now)


def test_forward_kinematics_matches_mujoco_through_a_maneuver(cfg):
    env = LhdLoadingEnv("rld", cfg)
    kin = ArmKinematics.from_config(cfg)
    env.reset(seed=3, options={"slope_deg": 25.0})
    for k in range(30):
        _, _, term, trunc, _ = env.step(np.array([1.0, -1.0 if k > 8 else 1.0, 1.0 if k > 5 else -1.0]))
        s = env.state
        pos, quat, v, joints, f, r = measurements(env)
        m = state_from_measurements(kin, pos, quat, v, joints, f, r)
        for a in ("x_shovel", "y_shovel", "z_shovel", "phi_shovel", "x_bottom", "z_bottom"):
            assert getattr(m, a) == pytest.approx(getattr(s, a), abs=FK_ATOL), a
        if term or trunc:
            break
    assert s.phi_boom < -0.1 and s.phi_bucket > 0.2     # the check covered a lifted, curled arm


def test_observation_from_measurements_equals_the_environments(cfg):
    env = LhdLoadingEnv("rlc", cfg, deploy_filter=True)
    rng = np.random.default_rng(0)
    core = PolicyCore(lambda o: rng.uniform(-1, 1, 3), "rlc", env.p, ArmKinematics.from_config(cfg))
    obs, _ = env.reset(seed=4)
    inp = Inputs()
    for _ in range(25):
        feed(inp, env, 0.0)
        assert np.abs(core.observation(inp) - obs).max() <= 1e-6
        obs, _, term, trunc, _ = env.step(rng.uniform(-1, 1, 3))
        if term or trunc:
            break


def test_decision_applies_the_deployment_filter_and_actuator_map(cfg, params):
    env = LhdLoadingEnv("rlc", cfg)
    env.reset(seed=1)
    a = np.array([0.3, 0.7, -0.95])      # boom above 0.6 -> still; bucket below -0.9 -> still
    core = PolicyCore(lambda o: a, "rlc", params, ArmKinematics.from_config(cfg))
    inp = Inputs()
    feed(inp, env, 10.0)
    d = core.decide(inp, 10.1, 0.5)
    assert d.reason == ""
    assert d.command == tuple(to_actuator(rlc_deploy_filter(a, params), params))
    assert d.command[1] == 0.0 and d.command[2] == 0.0


def test_zero_command_on_doubt(cfg, params):
    env = LhdLoadingEnv("rld", cfg)
    env.reset(seed=2)
    kin = ArmKinematics.from_config(cfg)
    core = PolicyCore(lambda o: np.ones(3), "rld", params, kin)
    inp = Inputs()
    assert core.decide(inp, 0.0, 0.5).command == ZERO_COMMAND                    # nothing received
    feed(inp, env, 0.0)
    assert core.decide(inp, 0.2, 0.5).command != ZERO_COMMAND
    d = core.decide(inp, 0.8, 0.5)                                                # every input stale
    assert d.command == ZERO_COMMAND and "0.80 s old" in d.reason
    feed(inp, env, 1.0)
    pos, quat, v = inp.values["odom"]
    inp.put("odom", (pos, quat, math.nan), 1.0)                                   # NaN speed
    d = core.decide(inp, 1.0, 0.5)
    assert d.command == ZERO_COMMAND and "non-finite" in d.reason
    inp.put("odom", (pos, (0.0, 0.0, 0.0, 0.0), v), 1.0)                          # broken quaternion
    assert "quaternion" in core.decide(inp, 1.0, 0.5).reason
    inp.put("odom", (pos, quat, v), 1.0)
    nan_actor = PolicyCore(lambda o: np.array([np.nan, 0, 0]), "rld", params, kin)
    assert nan_actor.decide(inp, 1.0, 0.5).command == ZERO_COMMAND
    assert PolicyCore(None, "rld", params, kin).decide(inp, 1.0, 0.5).reason == "no actor loaded"


def test_quaternion_rotation_is_proper():
    q = (math.cos(0.2), 0.0, math.sin(0.2), 0.0)    # 0.4 rad about y
    R = quat_to_mat(*q)
    assert np.allclose(R @ R.T, np.eye(3)) and np.linalg.det(R) == pytest.approx(1.0)
    assert R[0, 2] == pytest.approx(math.sin(0.4))


def test_slow_inputs_keep_their_own_timeout(cfg, params):
    """Slope and end zone come once per attempt (a latched constant, a LiDAR at 1-5 Hz): with no
    timeout for them, a 10 s old slope is fine while the 10 Hz inputs are fresh; with one, not."""
    env = LhdLoadingEnv("rld", cfg)
    env.reset(seed=2, options={"slope_deg": 20.0})
    core = PolicyCore(lambda o: np.ones(3), "rld", params, ArmKinematics.from_config(cfg), (15.0, 30.0))
    inp = Inputs()
    feed(inp, env, 0.0)
    feed(inp, env, 10.0)
    for name in ("slope", "end_zone"):          # published once, at t = 0
        inp.arrival[name] = 0.0
    assert "slope is 10.10 s old (timeout 0.5 s)" in core.decide(inp, 10.1, 0.5).reason
    assert core.decide(inp, 10.1, 0.5, {"slope": math.inf, "end_zone": math.inf}).reason == ""
    d = core.decide(inp, 10.1, 0.5, {"slope": 5.0, "end_zone": math.inf})
    assert d.command == ZERO_COMMAND and d.reason == "slope is 10.10 s old (timeout 5.0 s)" and d.kind == "inputs"
    d = core.decide(inp, 10.7, 0.5, {"slope": math.inf, "end_zone": math.inf})  # the 10 Hz inputs keep theirs
    assert d.command == ZERO_COMMAND and "joints is 0.70 s old (timeout 0.5 s)" in d.reason


@pytest.mark.parametrize("slope_deg, refused", [(10.0, True), (14.9, True), (15.0, False), (20.0, False),
                                                (30.0, False), (30.1, True), (40.0, True)])
def test_slope_outside_the_trained_range_is_refused_not_clipped(cfg, params, slope_deg, refused):
    env = LhdLoadingEnv("rld", cfg)
    env.reset(seed=2, options={"slope_deg": 20.0})
    core = PolicyCore(lambda o: np.ones(3), "rld", params, ArmKinematics.from_config(cfg), (15.0, 30.0))
    inp = Inputs()
    feed(inp, env, 0.0)
    inp.put("slope", math.radians(slope_deg), 0.0)
    d = core.decide(inp, 0.1, 0.5)
    if refused:
        assert d.command == ZERO_COMMAND and d.kind == "out_of_range" and d.observation is None
        assert d.reason == (f"slope {slope_deg:.1f} deg is outside the range the actor was trained on [15, 30] deg: "
                            "refused, not clipped")
    else:
        assert d.reason == "" and d.command != ZERO_COMMAND


def test_trained_range_from_the_card_or_its_training_config(cfg, tmp_path):
    import json
    import shutil

    from pathlib import Path

    from lhd_loading_ros.policy.actor_file import META_FILE, PolicyFileError, load_policy, seal_card

    d = tmp_path / "rld"
    shutil.copytree(Path(__file__).resolve().parents[2] / "policies" / "rld", d)
    meta = json.loads((d / META_FILE).read_text())

    def with_meta(**changes):
        m = {k: v for k, v in meta.items() if k != "trained_ranges"}
        m.update(changes)
        (d / META_FILE).write_text(json.dumps(m))     # actor.npz (and its SHA-256) untouched
        seal_card(d)                                  # a card exported so (an unsealed edit is refused)
        return load_policy(d)

    lo, hi, src = with_meta(trained_ranges={"slope_deg": [17.5, 27.5]}).trained_slope_range_deg(cfg)
    assert (lo, hi) == (17.5, 27.5) and "policy card" in src
    # no explicit field: the training config's episode range (15-30 deg), when the hashes agree
    from lhd_loading_ros.task.config import config_hash

    lo, hi, src = with_meta(config_hash=config_hash(cfg)).trained_slope_range_deg(cfg)
    assert (lo, hi) == (15.0, 30.0) and "training config" in src
    lo, hi, src = with_meta(config_hash="0000").trained_slope_range_deg(cfg)
    assert (lo, hi) == (15.0, 30.0) and "another config" in src
    for bad in ([30.0, 15.0], [15.0], ["15", 30.0], [15.0, math.inf]):
        with pytest.raises(PolicyFileError, match="trained_ranges.slope_deg"):
            with_meta(trained_ranges={"slope_deg": bad}).trained_slope_range_deg(cfg)
