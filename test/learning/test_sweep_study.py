"""lhd sweep's study files (learning/sweep.py load_study): the grid, the run folders, the
per-combination parameter files, and clear errors. No Ray here (test_sweep_ray.py runs one)."""
import json

import pytest
import yaml

from lhd_loading_ros.learning.sweep import StudyError, load_study


def write(tmp_path, study: dict):
    p = tmp_path / "study.yaml"
    p.write_text(yaml.safe_dump(study))
    return p


def test_grid_of_variants_seeds_presets_and_overrides(tmp_path):
    out, trials = load_study(write(tmp_path, {
        "out": "runs", "variants": ["rld", "rlc"], "seeds": "0-2", "randomize": [False, True], "steps": 5000,
        "overrides": {"paper.ddpg.actor_lr": [1e-4, 3e-4], "training.eval_episodes": 10}}))
    assert out == (tmp_path / "runs").resolve()
    assert len(trials) == 2 * 3 * 2 * 2
    groups = sorted({t.group for t in trials})
    assert groups == sorted(f"{v}{d}_actor_lr={lr}" for v in ("rld", "rlc") for d in ("", "_dr")
                            for lr in ("0.0001", "0.0003"))
    t = next(t for t in trials if t.group == "rlc_dr_actor_lr=0.0003" and t.seed == 2)
    assert t.run_dir == out / "rlc_dr_actor_lr=0.0003" / "seed_2"
    cmd = t.command()
    assert cmd[cmd.index("--variant") + 1] == "rlc" and cmd[cmd.index("--seed") + 1] == "2"
    assert "--randomize" in cmd and cmd[cmd.index("--steps") + 1] == "5000"
    cfg = t.settings["_config"]
    assert cfg["paper"]["ddpg"]["actor_lr"] == 3e-4 and cfg["training"]["eval_episodes"] == 10
    assert cmd[cmd.index("--config") + 1] == str(out / "configs" / "grid_actor_lr=0.0003.yaml")


def test_plain_study_uses_the_default_config_and_lhd_train_layout(tmp_path):
    out, trials = load_study(write(tmp_path, {"out": "r", "seeds": [3, 4]}))
    assert [(t.group, t.seed, t.randomize, t.config_path) for t in trials] == [("rld", 3, False, None),
                                                                               ("rld", 4, False, None)]
    assert "--config" not in trials[0].command() and "--steps" not in trials[0].command()


def test_done_needs_the_final_actor_with_the_studys_steps(tmp_path):
    _, (t,) = load_study(write(tmp_path, {"out": "r", "seeds": 0, "steps": 100}))
    assert not t.done()
    (t.run_dir / "final").mkdir(parents=True)
    (t.run_dir / "final" / "policy.json").write_text(json.dumps({"steps": 50}))
    assert not t.done()                 # a shorter earlier run is not this study's
    (t.run_dir / "final" / "policy.json").write_text(json.dumps({"steps": 100}))
    assert not t.done() and "config_hash None" in t.stale()     # nor one of another parameter file
    (t.run_dir / "final" / "policy.json").write_text(json.dumps({**t.expected(), "steps": 100}))
    assert t.done() and t.stale() is None


@pytest.mark.parametrize("study, why", [
    ({"variants": ["rld"]}, "'out'"),
    ({"out": "r", "variant": ["rld"]}, "unknown keys"),
    ({"out": "r", "variants": ["ppo"]}, "variants"),
    ({"out": "r", "seeds": "4-1"}, "seeds"),
    ({"out": "r", "randomize": ["yes"]}, "randomize"),
    ({"out": "r", "steps": 0}, "steps"),
    ({"out": "r", "overrides": {"paper.ddpg.no_such_key": [1, 2]}}, "no key 'no_such_key'"),
    ({"out": "r", "overrides": {"nosection.x": 1}}, "no section 'nosection'"),
    ({"out": "r", "overrides": {"training.eval_episodes": []}}, "empty list"),
    ({"out": "r", "overrides": {"training.eval_episodes": -5}}, "invalid parameter file"),
])
def test_bad_studies_are_refused_with_the_reason(tmp_path, study, why):
    with pytest.raises(StudyError, match=why):
        load_study(write(tmp_path, study))


def test_unreadable_study(tmp_path):
    with pytest.raises(StudyError, match="cannot read"):
        load_study(tmp_path / "missing.yaml")
    p = tmp_path / "bad.yaml"
    p.write_text("out: [unclosed")
    with pytest.raises(StudyError, match="not valid YAML"):
        load_study(p)


def test_cluster_address_is_checked_before_ray_joins_it():
    import socket

    from lhd_loading_ros.learning.sweep import check_address

    with socket.socket() as s:              # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(ConnectionError, match="ray start --head"):
        check_address(f"127.0.0.1:{port}", timeout=2.0)
    with pytest.raises(StudyError, match="expected HOST:PORT"):
        check_address("nonsense")
    with socket.socket() as srv:            # a listening port is accepted (ray://HOST:PORT too)
        srv.bind(("127.0.0.1", 0))
        srv.listen()
        check_address(f"ray://127.0.0.1:{srv.getsockname()[1]}")
    check_address("auto")


@pytest.mark.parametrize("study", [
    {"out": "r", "variants": ["rld", "rld"]},
    {"out": "r", "randomize": [True, True]},
    {"out": "r", "overrides": {"training.eval_episodes": [2, 2]}},
])
def test_a_value_given_twice_is_refused(tmp_path, study):
    with pytest.raises(StudyError, match="several trials"):
        load_study(write(tmp_path, study))


def test_close_values_get_their_own_folders_and_randomize_must_be_booleans(tmp_path):
    _, trials = load_study(write(tmp_path, {"out": "r", "overrides": {"paper.ddpg.actor_lr": [1.0e-4, 1.0000001e-4]}}))
    assert len({t.run_dir for t in trials}) == 2
    with pytest.raises(StudyError, match="randomize"):
        load_study(write(tmp_path, {"out": "r", "randomize": "true"}))
