"""task.reward_zones_from_pile: with a slope told wrong moving the zones (randomization.zones_from_slope_estimate),
the reward's terms read the pile's own zones, while the observation, the episode's end and so when r_success is
paid stay with the told ones. Checked on the real environment against a RewardTracker built here on the pile's
zones and stepped beside it; off (the default) the reward reads the told zones; out of the hash; on the card."""
PARALLEL_SAFE = True

import copy
from dataclasses import replace

import numpy as np
import pytest

from lhd_loading_ros.task.config import config_hash, validate
from lhd_loading_ros.task.randomization import NOMINAL
from lhd_loading_ros.task.reward import RewardTracker


def env_for(cfg, on: int):
    from lhd_sim_node.env import LhdLoadingEnv

    c = copy.deepcopy(cfg)
    c["task"]["reward_zones_from_pile"] = on
    return LhdLoadingEnv("rld", validate(c), zones_from_estimate=True)


@pytest.mark.parametrize("on", [0, 1])
def test_the_reward_reads_the_pile_s_zones_and_the_episode_ends_on_the_told_ones(cfg, on):
    env = env_for(cfg, on)
    env.reset(seed=7000, options={"slope_deg": 15.0, "material": "homogeneous",
                                  "conditions": replace(NOMINAL, slope_error_deg=15.0)})
    pile, told = env.sim.zones, env.zones
    assert told.x_max < pile.x_max - 0.1            # told 30 deg: the end zone told much shorter
    want = pile if on else told
    assert (env.reward_zones.x_min, env.reward_zones.x_max) == (want.x_min, want.x_max)
    # an independent tracker on the zones the reward should read, stepped beside the environment's
    ref = RewardTracker(env.p.for_pile(want), want, env.p.h_pile)
    ref.reset(env.sim.state(), env.sim.loaded_mass)
    other = pile if not on else told
    alt = RewardTracker(env.p.for_pile(other), other, env.p.h_pile)
    alt.reset(env.sim.state(), env.sim.loaded_mass)
    differ = 0
    # drive straight in with the wheels full, arm still: past the told x_min the rail and r_inact part the two
    for _ in range(60):
        _, r, term, trunc, info = env.step(np.array([1.0, 1.0, -1.0]))
        s, pl = env.sim.state(), env.sim.pile
        inside = 0.0 <= s.x_shovel < pl.L and s.z_shovel < pl.surface_height(s.x_shovel)
        u = info["command"]
        args = (s, u[1], u[2], env.sim.loaded_mass, inside, pl.surface_height(s.x_bottom), info["outcome"],
                env.sim.machine_pitch())
        assert r == pytest.approx(sum(ref.step(*args).values()), abs=1e-9)
        differ += abs(sum(alt.step(*args).values()) - r) > 1e-9
        # the episode ends by the told zones, whatever the reward reads
        assert info["x_max"] == told.x_max and info["x_min"] == told.x_min
        if term or trunc:
            break
    assert differ > 0, "the two zones never gave a different reward: the test does not tell them apart"


def test_off_by_default_out_of_the_hash_and_on_the_card(cfg, tmp_path):
    from lhd_loading_ros.learning.export import export_actor
    from lhd_loading_ros.learning.mlp import FlatMlp
    from lhd_loading_ros.learning.ship import _recipe_note
    from lhd_loading_ros.policy.actor_file import load_policy

    assert cfg["task"]["reward_zones_from_pile"] == 0
    c = copy.deepcopy(cfg)
    c["task"]["reward_zones_from_pile"] = 1
    c = validate(c)
    assert config_hash(c) == config_hash(cfg)
    export_actor(tmp_path / "a", FlatMlp([12, 8, 3], out_act="tanh"), c, {"variant": "rld", "seed": 0, "steps": 0})
    tw = load_policy(tmp_path / "a").meta["trained_with"]
    assert tw["reward_zones_from_pile"] == 1 and "reward's terms reading the pile's own zones" in _recipe_note(tw)
    export_actor(tmp_path / "b", FlatMlp([12, 8, 3], out_act="tanh"), cfg, {"variant": "rld", "seed": 0, "steps": 0})
    assert "reward_zones_from_pile" not in load_policy(tmp_path / "b").meta["trained_with"]
    bad = copy.deepcopy(cfg)
    bad["task"]["reward_zones_from_pile"] = 2
    with pytest.raises(Exception, match="reward_zones_from_pile"):
        validate(bad)


def test_refused_where_it_would_do_nothing(cfg, tmp_path):
    """Where no told slope moves the zones the reward reads the same zones either way: the configuration refuses
    the key without zones from the slope estimate or at the nominal density, and training refuses it (and
    demo_told_high) without domain randomisation, before anything is written."""
    from lhd_loading_ros.learning.train import train
    from lhd_loading_ros.task.config import ConfigError

    c = copy.deepcopy(cfg)
    c["task"]["reward_zones_from_pile"] = 1
    c["randomization"].update({"zones_from_slope_estimate": 0, "zones_at_nominal_density": 0})
    with pytest.raises(ConfigError, match="reward_zones_from_pile = 1 only with randomization.zones_from_slope_estimate"):
        validate(c)
    c["randomization"]["zones_at_nominal_density"] = 1
    assert validate(c)["task"]["reward_zones_from_pile"] == 1
    c["randomization"].update({"zones_from_slope_estimate": 1, "zones_at_nominal_density": 0, "enabled": 0})
    c = validate(c)
    with pytest.raises(ValueError, match=r"task.reward_zones_from_pile act only .* --randomize"):
        train("rld", 0, tmp_path / "run", steps=10, config=c, resume=False, progress=False)
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == [".train.lock"]   # nothing of a run written
    c["training"].update({"demo_share": 0.3, "demo_told_high": 7.5})
    with pytest.raises(ValueError, match=r"training.demo_told_high and task.reward_zones_from_pile act only"):
        train("rld", 0, tmp_path / "run", steps=10, config=validate(c), resume=False, progress=False)
