"""LhdLoading-v0: Gymnasium contract, determinism, validation of actions."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import lhd_sim_node  # noqa: F401  (registers LhdLoading-v0)
from lhd_sim_node.env import LhdLoadingEnv


@pytest.fixture(scope="module")
def env():
    return LhdLoadingEnv(variant="rld")


@pytest.mark.parametrize("variant", ["rld", "rlc"])
def test_check_env_passes(variant):
    e = gym.make("LhdLoading-v0", variant=variant)
    check_env(e.unwrapped, skip_render_check=True)
    assert e.observation_space.shape == (12,) and e.action_space.shape == (3,)


def test_seeded_resets_are_deterministic():
    a, b = LhdLoadingEnv(), LhdLoadingEnv()
    rng = np.random.default_rng(5)
    acts = rng.uniform(-1, 1, size=(40, 3))
    for e in (a, b):
        e.reset(seed=123)
    oa, ob = a.reset(seed=7)[0], b.reset(seed=7)[0]
    np.testing.assert_array_equal(oa, ob)
    for act in acts:
        ra, rb = a.step(act), b.step(act)
        np.testing.assert_array_equal(ra[0], rb[0])
        assert ra[1] == rb[1] and ra[2] == rb[2] and ra[3] == rb[3]
        if ra[2] or ra[3]:
            break
    # another seed gives another pile
    assert LhdLoadingEnv().reset(seed=8)[1]["alpha_deg"] != a.reset(seed=7)[1]["alpha_deg"]


def test_reset_options_fix_slope_and_material(env):
    _, info = env.reset(seed=1, options={"slope_deg": 25.0, "material": "nonhomogeneous"})
    assert info["alpha_deg"] == pytest.approx(25.0) and info["material"] == "nonhomogeneous"
    # the episode starts with the tip d_init = 0.1 m inside the pile
    assert 0.1 <= env.state.x_shovel < 0.13
    assert env.sim.d_attack >= 0.1 and env.sim.d_attack <= 0.2


def test_bad_actions_raise_before_the_physics(env):
    env.reset(seed=2)
    t0 = env.sim.data.time
    with pytest.raises(ValueError, match="non-finite"):
        env.step(np.array([0.0, np.nan, 0.0]))
    with pytest.raises(ValueError, match="out of range"):
        env.step(np.array([0.0, 0.0, 2.0]))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(4))
    assert env.sim.data.time == t0


def test_bad_construction_arguments():
    with pytest.raises(ValueError, match="variant must be one of"):
        LhdLoadingEnv(variant="ppo")
    with pytest.raises(ValueError, match="material must be one of"):
        LhdLoadingEnv(material="sand")
    with pytest.raises(ValueError, match=r"slope_deg = 45 degrees is outside the configured pile range \[15, 30\]"):
        LhdLoadingEnv(slope_deg=45)
    env = LhdLoadingEnv()
    for bad in (10.0, 30.5, float("nan")):       # per-episode options are checked too: refused, not clipped
        with pytest.raises(ValueError, match=r"options\['slope_deg'\] = .* outside the configured pile range"):
            env.reset(seed=0, options={"slope_deg": bad})
    env.reset(seed=0, options={"slope_deg": 30.0})   # the range's end is in it


def test_truncation_after_200_steps_is_not_termination(env):
    env.reset(seed=3, options={"slope_deg": 30.0, "material": "homogeneous"})
    still = np.array([-1.0, 1.0, -1.0])  # wheels off, arm still: nothing happens for 20 s
    for t in range(200):
        _, _, term, trunc, info = env.step(still)
        if t < 199:
            assert not term and not trunc
    assert trunc and not term
    assert info["episode_result"].truncated and info["episode_result"].steps == 200
    with pytest.raises(RuntimeError, match="finished episode"):
        env.step(still)


def test_rld_filter_reaches_the_actuators(env):
    env.reset(seed=4)
    _, _, _, _, info = env.step(np.array([0.0, 0.2, -0.3]))
    # boom a=0.2 > 0 -> +1 -> 0 rad/s; bucket -0.3 -> -1 -> 0 rad/s
    assert info["command"] == pytest.approx([1.35, 0.0, 0.0])
    rlc = LhdLoadingEnv(variant="rlc")
    rlc.reset(seed=4)
    _, _, _, _, info = rlc.step(np.array([0.0, 0.2, -0.3]))
    assert info["command"] == pytest.approx([1.35, -0.191 * 0.4, 0.2 * 0.35])


def test_a_misspelt_reset_option_is_refused_with_the_known_ones():
    """reset(options={"slop_deg": 20}) used to run a random slope without a word (a review)."""
    from lhd_loading_ros.task.config import load_config
    from lhd_sim_node.env import LhdLoadingEnv

    env = LhdLoadingEnv("rld", load_config())
    with pytest.raises(ValueError, match=r"unknown reset option 'slop_deg' \(did you mean 'slope_deg'\?\); expected "
                                         r"some of attack_speed, conditions, d_attack, material, slope_deg"):
        env.reset(seed=0, options={"slop_deg": 20.0})
    obs, _ = env.reset(seed=0, options={"slope_deg": 20.0, "material": "homogeneous"})
    assert obs.shape == (12,)


def test_a_stalled_attack_starts_where_it_stalled_only_when_the_config_allows_it(cfg):
    """sim.attack_min_depth: 0 (every file before it) keeps a stalled attack drive an AttackError; > 0
    starts the episode where the drive stalled if the tip is that far inside the pile. A 0.15 s drive
    from 1 cm before the toe at full speed stalls the tip about 4 cm in (the time limit stands in for a
    pile that stops the machine)."""
    import copy

    from lhd_loading_ros.task.config import ConfigError, config_hash, validate
    from lhd_sim_node.simulator import AttackError

    from lhd_loading_ros.task.randomization import Conditions

    opts = {"slope_deg": 20.0, "d_attack": 0.01, "attack_speed": 2.7}
    c = copy.deepcopy(cfg)
    c["sim"]["attack_timeout"] = 0.15
    for depth in (0.0, 0.09):
        c["sim"]["attack_min_depth"] = depth
        env = LhdLoadingEnv("rld", validate(copy.deepcopy(c)))
        with pytest.raises(AttackError, match=r"did not reach d_init = 0.1 m .* \(tip at x = 0.0\d\d m\)"):
            env.reset(seed=3, options=opts)
        assert not env.sim.attack_stalled
    c["sim"]["attack_min_depth"] = 0.01
    env = LhdLoadingEnv("rld", validate(copy.deepcopy(c)))
    obs, info = env.reset(seed=3, options=opts)
    tip = float(env.sim.data.site_xpos[env.sim.sid_tip][0])
    assert env.sim.attack_stalled and info["attack_stalled"] and 0.01 <= tip < 0.1
    assert np.all(np.isfinite(obs))
    _, r, te, tr, _ = env.step(np.array([1.0, -1.0, 1.0], dtype=np.float32))
    assert np.isfinite(r) and not tr
    # a start from rest after a stalled drive: the machine stands where it stalled
    obs, info = env.reset(seed=3, options={**opts, "conditions": Conditions(rest_start=True)})
    assert info["attack_stalled"] and abs(env.state.v_x) < 0.02
    assert 0.01 <= float(env.sim.data.site_xpos[env.sim.sid_tip][0]) < 0.1
    # the same simulator's next drive forgets the stall: asked for more depth than it gets, it raises unmarked
    env.sim.attack_min_depth = 0.09
    with pytest.raises(AttackError):
        env.reset(seed=3, options=opts)
    assert not env.sim.attack_stalled
    # and a drive that reaches d_init is never marked
    c2 = copy.deepcopy(cfg)
    c2["sim"]["attack_min_depth"] = 0.01
    env2 = LhdLoadingEnv("rld", validate(c2))
    obs, info = env2.reset(seed=3, options=opts)
    assert not info["attack_stalled"] and float(env2.sim.data.site_xpos[env2.sim.sid_tip][0]) >= 0.1
    # off (0) the key leaves the hash every file had; on it is part of the simulator's identity
    base = copy.deepcopy(cfg)
    without = copy.deepcopy(cfg)
    without["sim"].pop("attack_min_depth")
    assert config_hash(base) == config_hash(validate(without))
    base["sim"]["attack_min_depth"] = 0.05
    assert config_hash(base) != config_hash(validate(without))
    base["sim"]["attack_min_depth"] = 0.2
    with pytest.raises(ConfigError, match=r"sim.attack_min_depth <= paper.episode.d_init"):
        validate(base)
