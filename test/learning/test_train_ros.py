"""`lhd train --env ros`: one learner from two namespaced sim nodes started by `lhd up sim --count 2`
(separate processes over DDS). Both nodes contribute transitions, the run folder is a normal run
folder, and the exported actor runs in the policy node (`lhd up sim --policy ...`)."""
PARALLEL_SAFE = True   # lockstep sim nodes: the results do not depend on timing (test/conftest.py)
SERIAL = True          # but a whole pipeline end to end (38 s): `make test-stack`, not the default suite

import csv
import json
import os
import signal
import subprocess
import sys
import time
from collections import Counter

import pytest

from lhd_loading_ros.learning.train import train

from rosutil import unique_domain_id

STEPS = 2000


def _lhd(*args, **kw):
    return subprocess.Popen([sys.executable, "-m", "lhd_loading_ros.cli", *args], **kw)


@pytest.fixture
def domain(monkeypatch):
    monkeypatch.setenv("ROS_DOMAIN_ID", str(unique_domain_id()))


def test_train_from_two_sim_nodes_and_run_the_actor(domain, tmp_path):
    sims = _lhd("up", "sim", "--count", "2", "--namespace", "/trn", stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                text=True, start_new_session=True, env=dict(os.environ, PYTHONUNBUFFERED="1"))
    try:
        lines = []
        t_end = time.monotonic() + 120
        while time.monotonic() < t_end:
            line = sims.stdout.readline()
            if not line:
                break
            lines.append(line)
            if "sim nodes (lockstep) up in /trn0, /trn1" in line:
                break
        assert any("up in /trn0, /trn1" in ln for ln in lines), "".join(lines)
        out = tmp_path / "run"
        train("rld", 3, out, steps=STEPS - 600, progress=False, eval_episodes=2, eval_every=1000,
              checkpoint_every=700, env_kind="ros", namespaces=["/trn0", "/trn1"], log=lambda *a: None)
        # the same run longer: resumed from the checkpoint at 1,400 (every source's noise, its counts,
        # the episodes in progress started again first)
        logs = []
        ev = train("rld", 3, out, steps=STEPS, progress=False, eval_episodes=2, eval_every=1000,
                   checkpoint_every=700, env_kind="ros", namespaces=["/trn0", "/trn1"], log=logs.append)
        assert any("resumed" in m and "1,400" in m for m in logs), logs
        assert sims.poll() is None, "the sim nodes must still run"
    finally:
        os.killpg(sims.pid, signal.SIGTERM)
        rest = sims.communicate(timeout=30)[0]
    assert sims.returncode == 0, rest
    run = json.loads((out / "run.json").read_text())
    assert run["env"] == "ros" and run["sources"] == ["/trn0", "/trn1"]
    by_src = run["transitions_by_source"]
    assert by_src["/trn0"] > 0 and by_src["/trn1"] > 0 and sum(by_src.values()) == STEPS
    # stepped together: each node gave half the transitions
    assert abs(by_src["/trn0"] - by_src["/trn1"]) <= 1
    with open(out / "episodes.csv") as f:
        eps = list(csv.DictReader(f))
    per = Counter(e["source"] for e in eps)
    assert per["/trn0"] > 0 and per["/trn1"] > 0, per
    # every episode's seed index is used once: the episode numbers are distinct
    assert len({int(e["episode"]) for e in eps}) == len(eps)
    with open(out / "evals.csv") as f:
        assert [int(r["step"]) for r in csv.DictReader(f)] == [1000, 1400, 2000]
    assert ev["step"] == STEPS
    meta = json.loads((out / "final" / "policy.json").read_text())
    assert meta["variant"] == "rld" and meta["steps"] == STEPS, meta
    # the exported actor in the real policy node, against a sim node, one lockstep attempt
    p = subprocess.run([sys.executable, "-m", "lhd_loading_ros.cli", "up", "sim", "--policy", str(out / "final"),
                        "--mode", "lockstep", "--episodes", "1", "--slope", "20", "--namespace", "/trnp", "--json"],
                       capture_output=True, text=True, timeout=180)
    assert p.returncode == 0, p.stdout + p.stderr
    res = json.loads(p.stdout.strip().splitlines()[-1])
    assert res["attempts"] == 1 and 0.0 <= res["success_rate"] <= 1.0


def test_train_ros_without_sim_nodes_is_a_clear_error(domain, tmp_path):
    p = subprocess.run([sys.executable, "-m", "lhd_loading_ros.cli", "train", "--variant", "rld", "--env", "ros",
                        "--namespaces", "/nobody0", "--ros-timeout", "1", "--steps", "10", "--out", str(tmp_path / "r")],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 1, p.stdout + p.stderr
    assert "no sim node answers at /nobody0/lhd_sim" in p.stderr and "lhd up sim --count" in p.stderr
    p = subprocess.run([sys.executable, "-m", "lhd_loading_ros.cli", "train", "--variant", "rld", "--env", "ros"],
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 2 and "--namespaces" in p.stderr
