"""Demonstrations to the end of training (training.demo_until_step) and paired late changes:
a run keeps the checkpoint of a chosen step (`lhd train --keep-checkpoint N`), and another run
directory starts from it under a config whose training schedule differs (`--branch-from`).
Checked on short real runs: what the branch inherits is the source's record up to the step, what
differs after it is exactly the schedule's change (which episodes are demonstrations, by the
episode seeds' own draw), and what is refused."""
PARALLEL_SAFE = True

import copy
import csv
import json

import pytest
import torch

from lhd_loading_ros.learning.demonstrations import DemoConfig
from lhd_loading_ros.task.config import config_hash, validate


def small(cfg, until=0):
    c = copy.deepcopy(cfg)
    c["training"].update({"learning_starts": 256, "eval_episodes": 2, "eval_every": 150, "checkpoint_every": 150,
                          "hidden_sizes": [32, 32], "demo_share": 0.5, "demo_bc": 1.0, "noise_decay_steps": 300,
                          "demo_until_step": until})
    return c


def rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def test_demo_until_step_defaults_to_the_noise_decay_and_stays_out_of_the_hash(cfg):
    assert cfg["training"]["demo_until_step"] == 0
    d = DemoConfig.from_training(validate(small(cfg, 0))["training"])
    assert d.until_step == 300                               # noise_decay_steps, as before the key existed
    d = DemoConfig.from_training(validate(small(cfg, 600))["training"])
    assert d.until_step == 600
    assert d.draw(1, 599) == DemoConfig(0.5, 0.5, 0.75, 0.3, 10**9).draw(1, 0)   # the step only gates
    assert d.draw(1, 600) is None
    assert config_hash(validate(small(cfg, 0))) == config_hash(validate(small(cfg, 600)))
    old = copy.deepcopy(cfg)
    del old["training"]["demo_until_step"]                   # a parameter file written before the key
    assert validate(old)["training"]["demo_until_step"] == 0


def test_a_kept_checkpoint_branches_a_paired_run(cfg, tmp_path):
    from lhd_loading_ros.learning.train import episode_seed, train
    from lhd_loading_ros.policy.actor_file import load_policy

    quiet = dict(progress=False, log=lambda *a: None)
    a, b = tmp_path / "a", tmp_path / "b"
    train("rld", 3, a, steps=600, config=small(cfg, 0), keep_checkpoints=[300], **quiet)
    kept = torch.load(a / "checkpoint_step300.pt", weights_only=True)
    assert int(kept["step"]) == 300 and int(torch.load(a / "checkpoint.pt", weights_only=True)["step"]) == 600
    train("rld", 3, b, steps=600, config=small(cfg, 600), branch_from=a / "checkpoint_step300.pt", **quiet)
    ra, rb = rows(a / "episodes.csv"), rows(b / "episodes.csv")
    # the branch inherits the source's record up to the kept step, row for row
    early_a = [r for r in ra if int(r["step"]) <= 300]
    assert early_a and [r for r in rb if int(r["step"]) <= 300] == early_a
    assert [r for r in rows(b / "evals.csv") if int(r["step"]) <= 300] == \
           [r for r in rows(a / "evals.csv") if int(r["step"]) <= 300]
    # after it: the source's demonstrations stopped at noise_decay_steps, the branch's go on, each
    # episode's driver the draw of its own seed
    late_a, late_b = [r for r in ra if int(r["step"]) > 300], [r for r in rb if int(r["step"]) > 300]
    assert late_a and late_b and all(r["driver"] == "actor" for r in late_a)
    until = DemoConfig.from_training(validate(small(cfg, 600))["training"])
    for r in late_b:
        start = int(r["step"]) - int(r["steps"])
        want = until.draw(episode_seed(3, int(r["episode"]), cfg["training"]["episode_seed_offset"]), start)
        assert (want is None) == (r["driver"] == "actor"), r
    assert any(r["driver"] != "actor" for r in late_b)
    # the card and run.json say what the branch was trained with
    assert json.loads((b / "run.json").read_text())["demonstrations"]["until_step"] == 600
    tw_a, tw_b = load_policy(a / "final").meta["trained_with"], load_policy(b / "final").meta["trained_with"]
    assert tw_b["demo_until_step"] == 600 and tw_b["demo_bc"] == 1.0
    assert "demo_until_step" not in tw_a and tw_a["demonstrations"] == tw_b["demonstrations"]
    # going on again in the branch's directory resumes its own checkpoint (complete: nothing to do)
    assert train("rld", 3, b, steps=600, config=small(cfg, 600), branch_from=a / "checkpoint_step300.pt",
                 **quiet) == load_policy(b / "final").meta["evaluation"]


def test_what_is_refused(cfg, tmp_path):
    from lhd_loading_ros.learning.train import train

    quiet = dict(progress=False, log=lambda *a: None)
    with pytest.raises(ValueError, match=r"multiples of checkpoint_every \(150\)"):
        train("rld", 3, tmp_path / "x", steps=300, config=small(cfg), keep_checkpoints=[200], **quiet)
    with pytest.raises(ValueError, match="does not exist: expected a kept checkpoint .*--keep-checkpoint"):
        train("rld", 3, tmp_path / "y", steps=300, config=small(cfg), branch_from=tmp_path / "none.pt", **quiet)
    train("rld", 3, tmp_path / "a", steps=150, config=small(cfg), keep_checkpoints=[150], **quiet)
    src = tmp_path / "a" / "checkpoint_step150.pt"
    with pytest.raises(ValueError, match="belongs to variant rld seed 3, not rld seed 4"):
        train("rld", 4, tmp_path / "b", steps=300, config=small(cfg), branch_from=src, **quiet)
    other = small(cfg)
    other["paper"]["ddpg"]["gamma"] = 0.98                   # in the hash: not a paired schedule change
    with pytest.raises(ValueError, match="another parameter file"):
        train("rld", 3, tmp_path / "c", steps=300, config=other, branch_from=src, **quiet)


def test_the_cli_names_each_seeds_checkpoint(tmp_path, capsys):
    from lhd_loading_ros.cli.main import main

    rc = main(["train", "--variant", "rld", "--seeds", "0-1", "--out", str(tmp_path / "o"),
               "--branch-from", str(tmp_path / "checkpoint_step250000.pt")])
    assert rc == 2
    assert "{seed}" in capsys.readouterr().err
