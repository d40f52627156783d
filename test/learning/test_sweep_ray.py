"""`lhd sweep` on a local Ray: a two-trial study runs (two `lhd train` runs as Ray tasks), writes the
run folders `lhd report` reads and records its progress; the same study with more steps resumes
both trials from their checkpoints (what happens after a crash), and a last run skips what is done."""
PARALLEL_SAFE = True   # Ray tasks that train: no timing in the results (test/conftest.py)
SERIAL = True          # but a whole pipeline end to end (27 s, a Ray cluster): `make test-stack`

import json
import subprocess
import sys

import yaml


def lhd(*args, timeout=300):
    return subprocess.run([sys.executable, "-m", "lhd_loading_ros.cli", *args], capture_output=True, text=True,
                          timeout=timeout)


def test_two_trial_sweep_on_local_ray_and_report(tmp_path):
    study = tmp_path / "study.yaml"
    study.write_text(yaml.safe_dump({"out": "runs", "variants": ["rld"], "seeds": [0, 1], "steps": 150,
                                     "overrides": {"training.eval_episodes": 2, "training.eval_every": 75,
                                                   "training.checkpoint_every": 75}}))
    # a crash left trial seed_1 at its step-75 checkpoint: `lhd train` of that trial stopped there (the
    # study's own parameter file, as `lhd sweep` writes it for the overrides)
    from lhd_loading_ros.learning.sweep import _write_configs, load_study

    _, trials = load_study(study)
    _write_configs(trials)
    t1 = next(t for t in trials if t.seed == 1)
    cmd = t1.command()
    cmd[cmd.index("--steps") + 1] = "75"
    first = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert first.returncode == 0 and (t1.run_dir / "checkpoint.pt").exists(), first.stderr
    p = lhd("sweep", str(study), "--jobs", "2")
    assert p.returncode == 0, p.stdout + p.stderr
    assert "2 trials" in p.stdout and "0 already done, 2 to run" in p.stdout and "[2/2]" in p.stdout
    log1 = (tmp_path / "runs" / "rld" / "seed_1.log").read_text()
    assert "resumed" in log1 and "at step 75" in log1, log1          # seed_1 went on from its checkpoint
    assert "resumed" not in (tmp_path / "runs" / "rld" / "seed_0.log").read_text()
    status = json.loads((tmp_path / "runs" / "sweep_status.json").read_text())
    assert sorted(e["trial"] for e in status["finished"]) == ["rld/seed_0", "rld/seed_1"]
    assert not status["failed"] and not status["running"]
    for s in (0, 1):
        run = tmp_path / "runs" / "rld" / f"seed_{s}"
        assert json.loads((run / "final" / "policy.json").read_text())["steps"] == 150
        meta = json.loads((run / "run.json").read_text())
        assert meta["seed"] == s
    r = lhd("report", str(tmp_path / "runs" / "rld"), "--json")
    assert r.returncode == 0, r.stderr
    rep = json.loads(r.stdout.strip().splitlines()[-1])
    (s,) = rep.values()
    assert s["final_steps"] == [150, 150] and len(s["metrics"]["success_rate"]["values"]) == 2
    again = lhd("sweep", str(study))
    assert again.returncode == 0 and "2 already done, 0 to run" in again.stdout, again.stdout + again.stderr


def test_bad_study_is_a_clear_error(tmp_path):
    study = tmp_path / "study.yaml"
    study.write_text("out: runs\nvariants: [ppo]\n")
    p = lhd("sweep", str(study))
    assert p.returncode == 2 and "variants" in p.stderr and "rld" in p.stderr
