"""Scripted demonstrations in the replay (training.demo_share, learning/demonstrations.py): which
episodes are demonstrations (by hand and as a proportion), the maneuver on a real 15 deg pile
(the reason for the recipe: it loads far more than the actors, and ends curled past r_success's
pitch), a short real run whose replay holds the demonstrations' own actions, the card, the hash,
and what is refused."""
PARALLEL_SAFE = True

import copy
import csv
import math

import numpy as np
import pytest
import torch

from lhd_loading_ros.learning.demonstrations import DEMO_STREAM, DemoConfig, demo_action
from lhd_loading_ros.task.config import ConfigError, config_hash, validate


def demo_cfg(share=0.25, lo=0.5, hi=0.75, until=1000):
    return DemoConfig(share, lo, hi, 0.3, until)


def test_the_draw_by_hand():
    d = demo_cfg()
    for k in range(50):
        rng = np.random.default_rng([k, DEMO_STREAM])
        u = rng.random()
        expect = None if u >= 0.25 else 0.5 + 0.25 * rng.random()    # uniform(lo, hi) is lo + (hi - lo) U
        got = d.draw(k, 0)
        assert (got is None) == (expect is None)
        if got is not None:
            assert got == pytest.approx(expect, abs=1e-12)
            assert 0.5 <= got <= 0.75
        assert d.draw(k, 999) == got                  # the step does not enter the draw ...
        assert d.draw(k, 1000) is None                # ... but none starts at or after noise_decay_steps


def test_the_share_of_demonstrations():
    d = demo_cfg(share=0.2)
    n = 4000
    hits = sum(d.draw(k, 0) is not None for k in range(n))
    sd = math.sqrt(n * 0.2 * 0.8)                     # binomial: 800 +- 25
    assert abs(hits - 0.2 * n) < 4 * sd


def test_off_by_default_and_validated(cfg):
    assert DemoConfig.from_training(cfg["training"]) is None        # the shipped config: no demonstrations
    c = copy.deepcopy(cfg)
    c["training"].update({"demo_share": 0.3, "demo_crowd_min": 0.8, "demo_crowd_max": 0.6})
    with pytest.raises(ConfigError, match="demo_crowd_min <= training.demo_crowd_max"):
        validate(c)
    c["training"].update({"demo_crowd_min": 0.6, "demo_crowd_max": 0.8})
    d = DemoConfig.from_training(validate(c)["training"])
    assert (d.share, d.crowd_min, d.crowd_max, d.until_step) == (0.3, 0.6, 0.8, cfg["training"]["noise_decay_steps"])


def test_the_maneuver_on_a_15_deg_pile(cfg):
    """The reason for the recipe, measured on the real simulator: on a nominal 15 deg pile the
    demonstration drives with the arm still to the pile's x_min (or a wheel's drift), then lifts
    and curls with the wheels at its crowd; it loads more than 30 kg (the actors: 21-23 kg) and
    ends curled past the 43 deg that r_success asks with its pitch margin."""
    from lhd_sim_node.env import LhdLoadingEnv

    env = LhdLoadingEnv("rld", cfg)
    env.reset(seed=3000, options={"slope_deg": 15.0})
    crowd, x_min = 0.6, env.sim.zones.x_min
    lifted = False
    while True:
        s = env.state
        a = demo_action(env, crowd, 0.3)
        if s.x_shovel < x_min and not s.drift and s.phi_shovel < 0.02:   # (stateless: a drift that stops
            np.testing.assert_array_equal(a, [1.0, 1.0, -1.0])          # before the curl drives on) wheels full, arm still
        else:
            lifted = True
            assert a[0] == pytest.approx(2 * crowd - 1)                  # the crowd, as a normalised command
            assert a[2] == 1.0                                          # curling at full rate
        _, _, term, trunc, info = env.step(a)
        if term or trunc:
            r = info["episode_result"]
            break
    assert lifted and r.success and r.reached_end_zone
    assert r.loaded > 30.0
    assert math.degrees(r.phi_final) > 40.0 + 3.0
    assert r.max_tilt_deg < 3.0


def small(cfg, share):
    c = copy.deepcopy(cfg)
    c["training"].update({"learning_starts": 256, "eval_episodes": 2, "eval_every": 400, "checkpoint_every": 400,
                          "hidden_sizes": [32, 32], "demo_share": share})
    return c


def test_a_short_run_puts_the_demonstrations_in_the_replay(cfg, tmp_path):
    from lhd_loading_ros.learning.train import train
    from lhd_loading_ros.policy.actor_file import load_policy

    c = small(cfg, 0.5)
    train("rld", 3, tmp_path, steps=400, config=c, resume=False, progress=False)
    with open(tmp_path / "episodes.csv") as f:
        rows = list(csv.DictReader(f))
    drivers = [r["driver"] for r in rows]
    demos = [r for r in rows if r["driver"].startswith("scripted crowd ")]
    assert demos and "actor" in drivers
    crowds = [float(r["driver"].split()[-1]) for r in demos]
    assert all(0.5 <= x <= 0.75 for x in crowds)
    # which episodes were demonstrations follows from their seeds alone
    from lhd_loading_ros.learning.train import episode_seed

    d = DemoConfig.from_training(validate(c)["training"])
    exact = []
    for r in rows:
        want = d.draw(episode_seed(3, int(r["episode"])), 0)
        assert (want is None) == (r["driver"] == "actor")
        if want is not None:
            assert float(r["driver"].split()[-1]) == pytest.approx(want, abs=5e-4)
            exact.append(want)
    # the replay holds the demonstrations' actions: wheels at exactly 2 crowd - 1 while lifting,
    # which the actor's noisy, clipped actions hit with probability 0
    st = torch.load(tmp_path / "checkpoint.pt", weights_only=True)
    acts = st["replay"]["data"][:, 12:15].numpy().astype(np.float64)
    for x in exact:
        lifting = np.isclose(acts[:, 0], 2 * x - 1, atol=1e-6) & (acts[:, 2] == 1.0)
        assert lifting.sum() >= 3
    # the card records it; the hash does not
    meta = load_policy(tmp_path / "final").meta
    assert meta["trained_with"]["demonstrations"] == {"demo_share": 0.5, "demo_crowd_min": 0.5,
                                                      "demo_crowd_max": 0.75, "demo_pre_curl": 0.3}
    assert meta["config_hash"] == config_hash(validate(small(cfg, 0.0))) == config_hash(validate(c))


def test_the_sim_nodes_are_refused(cfg, tmp_path):
    from lhd_loading_ros.learning.train import train

    with pytest.raises(ValueError, match="demo_share > 0 .* needs the in-process environment"):
        train("rld", 0, tmp_path, steps=10, config=small(cfg, 0.2), resume=False, progress=False,
              env_kind="ros", namespaces=["/sim0"])
