"""An actor runs only under the observation scaling it was trained with.

build_observation scales the slope over [alpha_min, alpha_max] and the tip's position and d_end
over normalisers derived from the pile family (task.zones.derived_normalisers). An actor trained
on 10-35 deg piles and run under the shipped 15-30 deg parameter file would read a 15 deg pile as
0.0 instead of 0.2 and d_end over another length: every input shifted, silently. Its card records
the constants (observation.normalisers), and every place that pairs an actor with a parameter file
(policy node, supervisor, lhd eval / demo / up / experiment / report / ship) refuses a mismatch
with the reason; cards from before the record are checked by their trained slope range.
"""
import copy
import json
import math
import shutil
from pathlib import Path

import pytest

from lhd_loading_ros.learning.export import export_actor
from lhd_loading_ros.learning.mlp import FlatMlp
from lhd_loading_ros.policy.actor_file import META_FILE, PolicyFileError, load_policy
from lhd_loading_ros.task.config import load_config

ROOT = Path(__file__).resolve().parents[2]


def wide(cfg):
    c = copy.deepcopy(cfg)
    c["paper"]["episode"]["alpha_min_deg"], c["paper"]["episode"]["alpha_max_deg"] = 10.0, 35.0
    return c


def x_far_by_hand(cfg, alpha_deg):
    """Where the intact wedge between the toe and x holds m_max of the lightest gravel: the
    cross-section x^2 tan(alpha) / 2 below the crest (every pile here: h / tan(alpha) > 2 m),
    times the pile's width and density."""
    e, rho = cfg["paper"]["episode"], cfg["pile"]["density_min"]
    m_max = cfg["paper"]["end_zone"]["m_max"]
    x = math.sqrt(2.0 * m_max / (rho * e["w_pile"] * math.tan(math.radians(alpha_deg))))
    assert x < e["h_pile"] / math.tan(math.radians(alpha_deg))        # below the crest: the formula holds
    return x


@pytest.fixture
def wide_actor(cfg, tmp_path):
    net = FlatMlp([12, 8, 3], "tanh", generator=__import__("torch").Generator().manual_seed(0))
    return export_actor(tmp_path / "wide", net, wide(cfg), {"variant": "rld", "seed": 0})


def test_card_records_the_scaling_and_the_default_config_is_refused(cfg, wide_actor):
    card = json.loads((wide_actor / META_FILE).read_text())["observation"]["normalisers"]
    assert card["alpha_min"] == pytest.approx(math.radians(10.0)) and card["alpha_max"] == pytest.approx(math.radians(35.0))
    # d_end_max = x_far - d_init on the shallowest pile: 10 deg puts x_far farther than 15 deg
    d_init = cfg["paper"]["episode"]["d_init"]
    assert card["d_end_max"] == pytest.approx(x_far_by_hand(cfg, 10.0) - d_init, rel=1e-6)
    pol = load_policy(wide_actor)
    assert pol.observation_mismatch(wide(cfg)) is None
    why = pol.observation_mismatch(cfg)
    assert why is not None
    for name in ("alpha_min", "alpha_max", "d_end_max", "x_obs"):
        assert name in why, why
    assert "x_init_obs" not in why and "v_x_max" not in why          # only what differs is named
    assert f"{math.radians(10.0):.6g} in training, {math.radians(15.0):.6g} here" in why
    assert f"{x_far_by_hand(cfg, 10.0) - d_init:.6g} in training, {x_far_by_hand(cfg, 15.0) - d_init:.6g} here" in why
    with pytest.raises(PolicyFileError, match="another observation scaling"):
        pol.check_config(cfg)
    assert pol.check_config(wide(cfg)) is pol


def test_what_the_actor_does_not_see_may_differ(cfg, wide_actor):
    """The reward, the simulator, the randomisation: another parameter file, the same inputs."""
    c = wide(cfg)
    c["paper"]["reward"]["R_zone"] = 1234.0
    c["pile"]["k_uplift"] = 0.95
    c["randomization"]["enabled"] = 1
    assert load_policy(wide_actor).observation_mismatch(c) is None
    c["task"]["v_x_max"] = 0.6                                             # a normaliser: refused
    assert "v_x_max 0.5 in training, 0.6 here" in load_policy(wide_actor).observation_mismatch(c)


def test_older_cards_are_checked_by_their_trained_slope_range(cfg, tmp_path):
    d = tmp_path / "old"
    shutil.copytree(ROOT / "policies" / "rld", d)
    meta = json.loads((d / META_FILE).read_text())
    assert "normalisers" not in meta["observation"]                        # exported before the record
    assert load_policy(d).observation_mismatch(cfg) is None
    meta["trained_ranges"] = {"slope_deg": [10.0, 35.0]}
    meta.pop("card_sha256")                                                # cards of that time carry no seal
    (d / META_FILE).write_text(json.dumps(meta))                           # actor.npz (and its SHA) untouched
    why = load_policy(d).observation_mismatch(cfg)
    assert "trained on 10-35 deg piles" in why and "over 15-30 deg" in why
    assert load_policy(d).observation_mismatch(wide(cfg)) is None
    meta["observation"]["normalisers"] = {"alpha_min": float("nan")}
    (d / META_FILE).write_text(json.dumps(meta, allow_nan=True))
    with pytest.raises(PolicyFileError, match="observation.normalisers alpha_min are not finite numbers"):
        load_policy(d).observation_mismatch(cfg)


def test_every_shipped_actor_runs_under_the_shipped_config_or_its_own(cfg):
    """An actor shipped with its own parameter file (policies/rld_wide: 10-35 deg) runs under that
    file and is refused under the shipped one; every other runs under the shipped one."""
    dirs = [d for d in sorted((ROOT / "policies").iterdir()) if (d / META_FILE).is_file()]
    assert len(dirs) >= 2 and (ROOT / "policies" / "rld_wide" / "lhd_params.yaml").is_file()
    for d in dirs:
        own = d / "lhd_params.yaml"
        if own.is_file():
            assert load_policy(d).observation_mismatch(load_config(own)) is None, d
            assert load_policy(d).observation_mismatch(cfg) is not None, d
        else:
            assert load_policy(d).observation_mismatch(cfg) is None, d


def test_cli_refuses_a_mismatched_actor(cfg, wide_actor, tmp_path, capsys):
    from lhd_loading_ros.cli.main import main

    assert main(["eval", "--policy", str(wide_actor), "--episodes", "1"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("lhd eval: policy") and "another observation scaling" in err and "alpha_min" in err
    assert main(["experiment", "paper", "--controllers", "rld", "--rld", str(wide_actor), "--episodes", "1",
                 "--jobs", "1", "--out", str(tmp_path / "ex")]) == 2
    err = capsys.readouterr().err
    assert "lhd experiment paper: policy" in err and "d_end_max" in err
    assert not list((tmp_path / "ex").glob("*.csv"))                        # refused before any attempt ran
    # under the parameter file it was trained with, it runs
    import yaml

    f = tmp_path / "wide.yaml"
    f.write_text(yaml.safe_dump(wide(cfg)))
    assert main(["eval", "--policy", str(wide_actor), "--episodes", "1", "--config", str(f), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["episodes"] == 1


def test_the_actions_map_to_the_actuator_speeds_it_was_trained_with(cfg, wide_actor, tmp_path, capsys):
    """The card's action.actuator_low/high: -1 and +1 of each action in rad/s. A parameter file
    with wheels_max 2.16 instead of 2.7 (a review's way to model a slower machine) made every wheel
    command 20 % slow, silently: refused, naming the key and both values; for RLD the hybrid
    filter's threshold, which it was trained through, too. The reward may differ (above); the
    RLC deployment filter's saturations are a deployment choice, not judged."""
    c = wide(cfg)
    pol = load_policy(wide_actor)
    assert pol.action_mismatch(c) is None
    slow = copy.deepcopy(c)
    slow["paper"]["control"]["wheels_max"] = 2.16
    why = pol.action_mismatch(slow)
    assert "paper.control.wheels_max 2.7 in training, 2.16 here" in why and "boom" not in why
    assert "--stress slow_drive" in why
    with pytest.raises(PolicyFileError, match="actions mapped otherwise"):
        pol.check_config(slow)
    thr = copy.deepcopy(c)
    thr["task"]["rld_threshold"] = 0.2
    assert "task.rld_threshold 0 in training, 0.2 here" in pol.action_mismatch(thr)
    sat = copy.deepcopy(c)
    sat["task"]["rlc_boom_saturate"] = 0.5
    assert pol.action_mismatch(sat) is None
    # a card whose record is not 3 finite numbers
    d = tmp_path / "bad"
    shutil.copytree(wide_actor, d)
    meta = json.loads((d / META_FILE).read_text())
    meta["action"]["actuator_high"] = [2.7, 0.0]
    meta.pop("card_sha256", None)                  # unsealed: the record's own check, not the seal, is tested
    (d / META_FILE).write_text(json.dumps(meta))
    with pytest.raises(PolicyFileError, match=r"action.actuator_high = \[2.7, 0.0\]; expected 3 finite numbers"):
        load_policy(d).action_mismatch(c)
    # lhd eval refuses it before any episode
    from lhd_loading_ros.cli.main import main
    import yaml

    f = tmp_path / "slow.yaml"
    f.write_text(yaml.safe_dump(slow))
    assert main(["eval", "--policy", str(wide_actor), "--episodes", "1", "--config", str(f)]) == 1
    assert "paper.control.wheels_max 2.7 in training, 2.16 here" in capsys.readouterr().err
