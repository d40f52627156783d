"""`lhd train` as a user stops and restarts it (a review, 2026-11-29, twelfth session): SIGTERM to
`--seeds` (what `timeout` and `kill` send) left both children training, orphaned; the same command run
again then put two trainers on one run directory, which interleaved its episodes.csv. Real processes."""
import os
import signal
import subprocess
import sys
import time

import pytest

from lhd_loading_ros.learning.train import run_dir_lock

LHD = [sys.executable, "-m", "lhd_loading_ros.cli.main"]


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open(f"/proc/{pid}/stat") as f:           # a zombie is gone for this purpose
        return f.read().split(") ")[1][0] != "Z"


def _children_of(ppid: int) -> list[int]:
    out = subprocess.run(["ps", "-o", "pid=", "--ppid", str(ppid)], capture_output=True, text=True).stdout
    return [int(p) for p in out.split()]


def test_sigterm_to_train_seeds_stops_every_child(tmp_path):
    p = subprocess.Popen(LHD + ["train", "--variant", "rld", "--seeds", "0-1", "--jobs", "2", "--steps", "100000",
                                "--out", str(tmp_path / "runs")], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True)
    try:
        deadline = time.monotonic() + 60
        kids = []
        while time.monotonic() < deadline and len(kids) < 2:
            time.sleep(0.5)
            kids = _children_of(p.pid)
        assert len(kids) == 2, (kids, p.poll())
        # the children must be training (past imports) for the stop to mean anything: their logs grow
        while time.monotonic() < deadline and not all((tmp_path / "runs" / f"seed_{s}" / "run.json").exists()
                                                      for s in (0, 1)):
            time.sleep(0.5)
        p.send_signal(signal.SIGTERM)
        out, err = p.communicate(timeout=60)
        assert p.returncode == 130, (out, err)
        assert "interrupted; rerun the same command to resume" in err
        assert not [k for k in kids if _alive(k)], "children still training after the parent's SIGTERM"
    finally:
        if p.poll() is None:
            p.kill()
        for k in _children_of(p.pid):
            os.killpg(k, signal.SIGKILL)


def test_a_second_trainer_on_the_same_run_directory_is_refused(tmp_path):
    run = tmp_path / "seed_0"
    with run_dir_lock(run):
        r = subprocess.run(LHD + ["train", "--variant", "rld", "--seed", "0", "--steps", "200", "--out", str(run)],
                           capture_output=True, text=True, timeout=120)
        assert r.returncode == 1, r.stderr[-800:]
        assert f"another lhd train is writing {run} (pid {os.getpid()})" in r.stderr and "Traceback" not in r.stderr
    with run_dir_lock(run):         # released at the end of the block: the directory takes a trainer again
        pass


@pytest.mark.parametrize("args, needle", [
    (["--seed", "5", "--seeds", "0-1"], "--seed 5 and --seeds 0-1 are alternatives"),
])
def test_train_argument_conflicts_are_one_line(args, needle, tmp_path):
    r = subprocess.run(LHD + ["train", "--variant", "rld", "--out", str(tmp_path / "x"), *args], capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 2 and needle in r.stderr and "Traceback" not in r.stderr, r.stderr[-800:]


def test_failed_seeds_say_why_in_the_parents_message(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text((__import__("pathlib").Path(__file__).parents[2] / "config" / "lhd_params.yaml").read_text()
                   .replace("  eval_episodes: 120", "  eval_episodez: 120"))
    r = subprocess.run(LHD + ["train", "--variant", "rld", "--seeds", "0-1", "--steps", "200", "--config", str(bad),
                              "--out", str(tmp_path / "runs")], capture_output=True, text=True, timeout=180)
    assert r.returncode == 1, r.stderr[-800:]
    assert "failed seeds:" in r.stderr and "seeds 0, 1: lhd train:" in r.stderr and "eval_episodez" in r.stderr
