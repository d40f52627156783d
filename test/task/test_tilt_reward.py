"""r_tilt (task.r_tilt_per_deg, training-only): the cost of tipping the machine, by hand; off, the
reward and the config hash are what they were; on, an actor trained with it runs on the shipped config."""
import copy
import math

import numpy as np
import pytest

from lhd_loading_ros.task.config import config_hash, hash_matches
from lhd_loading_ros.task.params import TaskParams
from lhd_loading_ros.task.reward import r_tilt


def with_tilt(cfg, per_deg, free=3.0):
    c = copy.deepcopy(cfg)
    c["task"]["r_tilt_per_deg"], c["task"]["r_tilt_free_deg"] = per_deg, free
    return c


@pytest.mark.parametrize("pitch_deg, expected", [(0.0, 0.0), (2.9, 0.0), (-3.0, 0.0), (10.0, -70.0), (-13.0, -100.0),
                                                 (28.0, -250.0)])
def test_cost_per_degree_beyond_the_free_pitch(cfg, pitch_deg, expected):
    p = TaskParams.from_config(with_tilt(cfg, 10.0, 3.0))
    assert r_tilt(math.radians(pitch_deg), p) == pytest.approx(expected, abs=1e-9)


def test_off_by_default_and_out_of_the_hash(cfg):
    assert cfg["task"]["r_tilt_per_deg"] == 0.0
    assert TaskParams.from_config(cfg).r_tilt_per_deg == 0.0
    # off, the keys do not enter the hash: actors trained before they existed keep theirs
    stripped = copy.deepcopy(cfg)
    del stripped["task"]["r_tilt_per_deg"], stripped["task"]["r_tilt_free_deg"]
    assert config_hash(cfg) == config_hash(stripped) == config_hash(with_tilt(cfg, 0.0, 7.0))
    on = with_tilt(cfg, 10.0)
    assert config_hash(on) != config_hash(cfg) != config_hash(with_tilt(cfg, 20.0))
    # an actor trained with it runs on the shipped config when its card says so, and vice versa
    assert hash_matches(config_hash(on), cfg, trained_tilt=(10.0, 3.0))
    assert not hash_matches(config_hash(on), cfg)
    assert hash_matches(config_hash(cfg), on)
    assert not hash_matches(config_hash(with_tilt(cfg, 5.0)), cfg, trained_tilt=(10.0, 3.0))


def test_in_the_environment_only_while_on(cfg):
    """A seeded episode: off, no 'tilt' term and the same rewards as with the keys at any free
    pitch; on, the term is -per_deg x the excess of the machine's pitch the info reports."""
    from lhd_sim_node.env import LhdLoadingEnv

    def episode(c, steps=25):
        env = LhdLoadingEnv(config=c, variant="rld")
        env.reset(seed=3, options={"slope_deg": 30.0})
        out = []
        for k in range(steps):
            _, r, term, trunc, info = env.step(np.array([1.0, 1.0 if k > 5 else 0.0, 0.3]))
            out.append((r, dict(info["terms"]), env.sim.machine_pitch()))
            if term or trunc:
                break
        return out

    off, off2 = episode(cfg), episode(with_tilt(cfg, 0.0, 9.0))
    assert [r for r, _, _ in off] == [r for r, _, _ in off2]
    assert all("tilt" not in t for _, t, _ in off)
    on = episode(with_tilt(cfg, 10.0, 0.0))
    assert len(on) == len(off) and any(t["tilt"] < 0.0 for _, t, _ in on)   # the machine pitched, and it cost
    for (r_on, t_on, pitch), (r_off, _, _) in zip(on, off):
        excess = math.degrees(abs(pitch))
        assert t_on["tilt"] == pytest.approx(-10.0 * excess, abs=1e-9)
        assert r_on == pytest.approx(r_off + t_on["tilt"], abs=1e-6)


def test_an_actor_trained_with_the_tilt_penalty_runs_on_the_shipped_config(cfg, tmp_path):
    """The exported card records the penalty (trained_with), and the nodes' check
    (LoadedPolicy.config_matches) accepts the actor on the shipped config because of it."""
    import json

    from lhd_loading_ros.learning.ddpg import DdpgAgent, DdpgConfig
    from lhd_loading_ros.learning.export import export_actor
    from lhd_loading_ros.policy.actor_file import load_policy, seal_card

    on = with_tilt(cfg, 10.0, 3.0)
    agent = DdpgAgent(DdpgConfig.from_config(on), seed=0)
    d = export_actor(tmp_path / "p", agent.actor, on, {"variant": "rld", "seed": 0, "steps": 0})
    pol = load_policy(d)
    assert pol.meta["trained_with"]["r_tilt_per_deg"] == 10.0 and pol.meta["trained_with"]["r_tilt_free_deg"] == 3.0
    assert pol.config_matches(cfg) and pol.config_matches(on)
    meta = json.loads((d / "policy.json").read_text())
    del meta["trained_with"]["r_tilt_per_deg"]          # a card that does not say so: another config
    (d / "policy.json").write_text(json.dumps(meta))
    seal_card(d)                                        # exported so (an unsealed edit is refused: test_policy_core)
    assert not load_policy(d).config_matches(cfg)
