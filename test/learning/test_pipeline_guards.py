"""Guards of the training pipeline found by a review (2026-11-30): lhd ship's --out, seeds that are not
alike, lhd sweep's stale trials, lhd report's colliding group names, lhd experiment's actor variants,
lhd train's --no-resume / --jobs / unreadable checkpoints. Fast: fake run folders, no training."""
import csv
import json
from pathlib import Path

import pytest

from lhd_loading_ros.learning.export import export_actor
from lhd_loading_ros.learning.mlp import FlatMlp


def fake_run(cfg, run_dir: Path, variant="rld", seed=0, steps=300, sub=("final",), **meta) -> Path:
    """A run folder as lhd train leaves it: evals.csv, run.json and exported actors (untrained)."""
    run_dir.mkdir(parents=True, exist_ok=True)
    with open(run_dir / "evals.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=["step", "ar", "aml", "asl", "success_rate"])
        w.writeheader()
        w.writerow({"step": steps, "ar": 1.0, "aml": 2.0, "asl": 0.5, "success_rate": 0.25})
    (run_dir / "run.json").write_text(json.dumps({"variant": variant, "seed": seed, "ddpg": {"total_steps": steps}}))
    for name in sub:
        export_actor(run_dir / name, FlatMlp([12, 8, 3], "tanh"), cfg,
                     {"variant": variant, "seed": seed, "steps": steps, "evaluation": {}, **meta})
    return run_dir


# --- 1. lhd ship --out ---------------------------------------------------------------------------------

@pytest.fixture
def runs(cfg, tmp_path):
    d = tmp_path / "runs"
    for s in (0, 1):
        fake_run(cfg, d / f"seed_{s}", seed=s)
    return d


@pytest.mark.parametrize("where, why", [
    ("runs", "is the training runs"),
    (".", "contains the training runs"),
    ("runs/seed_0", "lies inside the training runs"),
    ("runs/seed_0/final", "lies inside the training runs"),
    ("runs/new", "lies inside the training runs"),
])
def test_ship_refuses_an_out_that_would_delete_the_runs(runs, tmp_path, where, why):
    from lhd_loading_ros.learning.ship import ship

    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    with pytest.raises(ValueError, match=why):
        ship("rld", runs, tmp_path / where, episodes=1, log=lambda *a: None)
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before      # nothing touched


def test_ship_refuses_an_out_that_is_not_a_policy_folder(runs, tmp_path):
    from lhd_loading_ros.learning.ship import check_out, ship

    other = tmp_path / "thesis"
    other.mkdir()
    (other / "chapter1.tex").write_text("precious")
    with pytest.raises(ValueError, match="is not a policy folder \\(no policy.json\\)"):
        ship("rld", runs, other, episodes=1, log=lambda *a: None)
    assert (other / "chapter1.tex").read_text() == "precious"
    (tmp_path / "file").write_text("x")
    with pytest.raises(ValueError, match="not a folder"):
        check_out(tmp_path / "file", runs)
    # a policy folder (policy.json), a new folder or an empty one are fine
    check_out(runs / "seed_0" / "final", tmp_path / "elsewhere")
    check_out(tmp_path / "policies" / "rld", runs)
    (tmp_path / "empty").mkdir()
    check_out(tmp_path / "empty", runs)


def test_ship_installs_the_new_folder_in_place_of_the_old(tmp_path):
    from lhd_loading_ros.learning.ship import _install

    out, tmp = tmp_path / "pol", tmp_path / ".pol.tmp"
    out.mkdir()
    (out / "policy.json").write_text("old")
    (out / "stale.png").write_text("old")
    tmp.mkdir()
    (tmp / "policy.json").write_text("new")
    _install(tmp, out)
    assert sorted(p.name for p in out.iterdir()) == ["policy.json"] and (out / "policy.json").read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pol"]     # neither the temporary nor the old left


# --- 6. seeds that are not alike -----------------------------------------------------------------------

def test_ship_refuses_seeds_of_different_lengths_or_configs(cfg, tmp_path):
    from lhd_loading_ros.learning.ship import ship

    runs = tmp_path / "runs"
    fake_run(cfg, runs / "seed_0", seed=0, steps=300)
    fake_run(cfg, runs / "seed_1", seed=1, steps=600)
    with pytest.raises(ValueError, match="different numbers of steps \\(seed_0 300, seed_1 600\\)"):
        ship("rld", runs, tmp_path / "pol", episodes=1, log=lambda *a: None)
    fake_run(cfg, runs / "seed_1", seed=1, steps=300, config_hash="0123456789abcdef")
    with pytest.raises(ValueError, match="different parameter files .*seed_1 0123456789abcdef"):
        ship("rld", runs, tmp_path / "pol", episodes=1, log=lambda *a: None)
    assert not (tmp_path / "pol").exists()


# --- 2. lhd train --no-resume ----------------------------------------------------------------------------

def tiny(cfg):
    cfg["training"].update({"learning_starts": 256, "eval_episodes": 1, "hidden_sizes": [8, 8]})
    return cfg


def test_no_resume_moves_the_previous_run_aside(cfg, tmp_path):
    from lhd_loading_ros.learning.train import train

    run = fake_run(cfg, tmp_path / "seed_0", sub=("best", "final"))
    (run / "checkpoint.pt").write_bytes(b"old")
    (run / "checkpoint_step150.pt").write_bytes(b"old kept")
    logs = []
    train("rld", 0, run, steps=2, config=tiny(cfg), resume=False, progress=False, eval_every=2, checkpoint_every=2,
          log=logs.append)
    (prev,) = run.glob("previous_*")
    assert sorted(p.name for p in prev.iterdir()) == ["best", "checkpoint.pt", "checkpoint_step150.pt", "evals.csv",
                                                      "final", "run.json"]
    assert (prev / "checkpoint.pt").read_bytes() == b"old"
    assert not (run / "checkpoint_step150.pt").exists()
    assert json.loads((run / "final" / "policy.json").read_text())["steps"] == 2      # the new run's
    assert any("moved the previous run's files to" in m and "nothing deleted" in m for m in logs)


# --- 3. lhd sweep: finished trials of other settings -------------------------------------------------------

def test_sweep_refuses_finished_trials_of_changed_settings(cfg, tmp_path):
    import yaml

    from lhd_loading_ros.learning.sweep import StudyError, _write_configs, load_study, sweep
    from lhd_loading_ros.learning.train import train

    (tmp_path / "tiny.yaml").write_text(yaml.safe_dump(tiny(cfg)))
    study = {"out": "r", "seeds": 0, "steps": 2, "config": "tiny.yaml",
             "overrides": {"training.eval_every": 2, "training.checkpoint_every": 2}}
    p = tmp_path / "study.yaml"
    p.write_text(yaml.safe_dump(study))
    _, (t,) = load_study(p)
    _write_configs([t])
    train(t.variant, t.seed, t.run_dir, steps=t.steps, config=str(t.config_path), progress=False, log=lambda *a: None)
    assert t.done() and t.stale() is None          # what the trial's own lhd train records is what it expects
    # a fixed override changed (not in the group's name), or fewer steps than it has: refused by name, not skipped
    for change in ({"overrides": {**study["overrides"], "training.eval_episodes": 2}}, {"steps": 1}):
        p.write_text(yaml.safe_dump({**study, **change}))
        with pytest.raises(StudyError, match="1 finished trial\\(s\\) were trained under other settings.*rld/seed_0 "
                                             "\\((config_hash .* != |steps 2 > 1)"):
            sweep(p, log=lambda *a: None)
    assert json.loads((t.run_dir / "final" / "policy.json").read_text())["steps"] == 2     # left as it was
    # more steps (or none: the file's total_steps) is the study going on: not done, resumed, not refused
    for change in ({"steps": 4}, {"steps": None}):
        p.write_text(yaml.safe_dump({**study, **change}))
        _, (t2,) = load_study(p)
        assert t2.stale() is None and not t2.done()


# --- 4. lhd report: two groups of one name ------------------------------------------------------------------

def test_report_keeps_groups_that_share_a_name(cfg, tmp_path, capsys):
    from lhd_loading_ros.cli.main import main
    from lhd_loading_ros.learning.report import group_labels

    for study, steps in (("study1", 300), ("study2", 600)):
        for s in (0, 1):
            fake_run(cfg, tmp_path / study / "rld" / f"seed_{s}", seed=s, steps=steps, sub=())
    a, b = tmp_path / "study1" / "rld", tmp_path / "study2" / "rld"
    assert main(["report", str(a), str(b), "--json", "--plot", str(tmp_path / "curves.png")]) == 0
    res = json.loads(capsys.readouterr().out)
    assert sorted(res) == ["study1/rld", "study2/rld"]
    assert res["study2/rld"]["final_steps"] == [600, 600]
    assert group_labels([a, tmp_path / "study1" / "rlc"]) == ["rld", "rlc"]      # unique names stay short
    twice = group_labels([a, a])                                                   # a path given twice
    assert twice[1] == twice[0] + " (2)"
    assert main(["report", str(a), str(a), "--json"]) == 0                         # through the command too
    res = json.loads(capsys.readouterr().out)
    assert len(res) == 2 and sorted(res)[1] == sorted(res)[0] + " (2)", sorted(res)


# --- 5. lhd experiment paper: an actor of the other variant ----------------------------------------------------

REPO = Path(__file__).resolve().parents[2]


def test_experiment_refuses_an_actor_of_the_other_variant(tmp_path):
    from lhd_loading_ros.cli.main import main
    from lhd_loading_ros.learning import experiment as ex

    jobs = ex.grid(("rld",), (20.0,), ("homogeneous",), (), episodes=1)
    with pytest.raises(ValueError, match="--rld .*policies/rlc is an RLC actor, not RLD"):
        ex.run(jobs, 1, None, {"rld": str(REPO / "policies" / "rlc")}, progress=None)
    assert main(["experiment", "paper", "--controllers", "rld", "--rld", str(REPO / "policies" / "rlc"),
                 "--out", str(tmp_path / "exp")]) == 2
    assert not (tmp_path / "exp").exists()


# --- 9. lhd experiment paper into the folder of an earlier run --------------------------------------------------

def test_experiment_removes_the_previous_runs_files_first(tmp_path):
    import io

    from lhd_loading_ros.learning import experiment as ex

    out = tmp_path / "exp"
    out.mkdir()
    for f in ("table_paired.md", "table_paired.csv", "tip_trajectories.png", "summary.json"):
        (out / f).write_text("from an earlier run")
    (out / "notes.txt").write_text("mine")
    said = io.StringIO()
    ex.paper(out, 1, ("tampier",), (20.0,), ("homogeneous",), (), jobs_n=1, progress=said)
    assert not (out / "table_paired.md").exists() and not (out / "table_paired.csv").exists()
    assert (out / "notes.txt").read_text() == "mine"                   # not one of its files: left alone
    assert json.loads((out / "summary.json").read_text())["controllers"] == ["tampier"]
    assert "removed the previous run's table_paired.csv, table_paired.md, summary.json" in said.getvalue()
    assert (out / "tip_trajectories.png").read_bytes() != b"from an earlier run"


# --- 10. lhd train --seeds --jobs -1 ---------------------------------------------------------------------------

def test_train_refuses_a_negative_jobs(tmp_path, capsys):
    from lhd_loading_ros.cli.main import main
    from lhd_loading_ros.learning.runner import run_seeds

    assert main(["train", "--variant", "rld", "--seeds", "0-1", "--jobs", "-1", "--out", str(tmp_path / "r")]) == 2
    assert "--jobs must be >= 0 (0: one per core), got -1" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()
    with pytest.raises(ValueError, match="jobs must be >= 1, got 0"):
        run_seeds("rld", [0, 1], tmp_path / "r", 0, [])


# --- 7. a plain resume under another training schedule; 11b. an unreadable checkpoint -------------------------

def test_a_plain_resume_under_another_schedule_is_refused(cfg, tmp_path):
    import copy

    from lhd_loading_ros.learning.train import train

    quiet = {"progress": False, "log": lambda *a: None, "eval_every": 2, "checkpoint_every": 2}
    run = tmp_path / "seed_0"
    train("rld", 0, run, steps=2, config=tiny(cfg), **quiet)
    other = copy.deepcopy(cfg)
    other["training"]["critic_huber"] = 1.0          # left out of the config hash on purpose (--branch-from)
    with pytest.raises(ValueError, match="another training schedule: training.critic_huber 0.0 -> 1.0; .*--branch-from"):
        train("rld", 0, run, steps=4, config=other, **quiet)
    assert train("rld", 0, run, steps=4, config=cfg, **quiet)["step"] == 4      # the schedule it had: goes on
    # a checkpoint that predates a schedule key (2026-11-30: demo_push_curl / demo_late_lift) had its default:
    # the same schedule, resumed (a review found every run from before the keys refused)
    import torch
    st = torch.load(run / "checkpoint.pt", weights_only=False)
    sched = json.loads(st["schedule"])
    assert "training.critic_huber" in sched
    del sched["training.critic_huber"]                    # its default 0.0 is what cfg has
    st["schedule"] = json.dumps(sched)
    torch.save(st, run / "checkpoint.pt")
    assert train("rld", 0, run, steps=6, config=cfg, **quiet)["step"] == 6
    # 11b: a truncated or empty checkpoint: one message saying what to do, no traceback of torch's
    good = (run / "checkpoint.pt").read_bytes()
    for broken in (good[: len(good) // 2], b""):
        (run / "checkpoint.pt").write_bytes(broken)
        with pytest.raises(ValueError, match="checkpoint.pt unreadable \\(.*\\): remove it or use --no-resume"):
            train("rld", 0, run, steps=8, config=cfg, **quiet)


# --- 11a. an actor of the wrong input or output size --------------------------------------------------------------

@pytest.mark.parametrize("sizes", [[11, 8, 3], [12, 8, 2]])
def test_an_actor_of_the_wrong_size_is_refused_when_loaded(cfg, tmp_path, sizes):
    from lhd_loading_ros.policy.actor_file import PolicyFileError, load_policy

    export_actor(tmp_path / "pol", FlatMlp(sizes, "tanh"), cfg, {"variant": "rld", "seed": 0, "steps": 1})
    with pytest.raises(PolicyFileError, match=f"maps {sizes[0]} inputs to {sizes[-1]} outputs .*expected 12 .* to 3"):
        load_policy(tmp_path / "pol")


# --- 11c. lhd train without PyTorch ---------------------------------------------------------------------------

def test_train_without_torch_says_so_in_one_line(tmp_path, capsys, monkeypatch):
    import sys

    from lhd_loading_ros.cli.main import main

    monkeypatch.setitem(sys.modules, "torch", None)          # import torch raises ImportError
    assert main(["train", "--variant", "rld", "--steps", "2", "--out", str(tmp_path / "r")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "torch==2.13.0 --index-url https://download.pytorch.org/whl/cpu" in err
    assert not (tmp_path / "r").exists()


# --- 11e. the IQM of values with a NaN --------------------------------------------------------------------------

def test_iqm_does_not_hide_a_nan():
    import math

    from lhd_loading_ros.learning.report import iqm

    assert iqm([1.0, 2.0, 3.0, 4.0]) == 2.5
    assert math.isnan(iqm([1.0, 2.0, 3.0, float("nan")]))       # was 2.5: the NaN sorted last and dropped
    assert math.isnan(iqm([float("nan")] * 4))
