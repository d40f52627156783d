"""`lhd demo --scripted` honours the demo's flags that apply to it (`--episodes N`: N attempts in all,
cycling through the slopes as the nodes' demo does; `--slope`/`--slopes`, `--material`, `--seed`,
`--json`) and refuses by name the flags that only concern the nodes; it ignored them all before
(2026-11-28: `--episodes 2` printed 3 attempts per slope). `lhd demo --help` shows the real
defaults, `lhd config check --help` says what it does."""
PARALLEL_SAFE = True   # command-line runs that only compute (test/conftest.py)

import json
import subprocess
import sys
from types import SimpleNamespace

import pytest

from lhd_loading_ros.cli.demo import scripted_plan, scripted_problem
from lhd_loading_ros.cli.launcher import main as launcher_main

LHD = [sys.executable, "-m", "lhd_loading_ros.cli.main"]


@pytest.mark.parametrize("slopes, episodes, plan", [
    ([15, 20, 25, 30], 12, [(15.0, 3), (20.0, 3), (25.0, 3), (30.0, 3)]),   # the default: 3 per slope
    ([15, 20, 25, 30], 2, [(15.0, 1), (20.0, 1)]),                         # the nodes' cycle: 15, 20
    ([15, 20, 25, 30], 6, [(15.0, 2), (20.0, 2), (25.0, 1), (30.0, 1)]),
    ([25.0], 4, [(25.0, 4)]),
    ([20, 20, 30], 4, [(20.0, 3), (30.0, 1)]),                             # a repeated slope counted once
])
def test_scripted_plan_cycles_like_the_nodes_demo(slopes, episodes, plan):
    assert scripted_plan(slopes, episodes) == plan
    assert sum(n for _, n in plan) == episodes


def _args(**kw):
    base = dict(policy=None, mode=None, namespace=None, use_sim_time=False, log_dir=None, verbose=False,
                material="homogeneous", episodes=12)
    return SimpleNamespace(**{**base, **kw})


def test_scripted_problem_names_the_flags_that_do_not_apply():
    assert scripted_problem(_args()) == ""
    why = scripted_problem(_args(policy="policies/rlc", use_sim_time=True))
    assert "--policy, --use-sim-time apply to the nodes only" in why
    assert "--mode applies to the nodes only" in scripted_problem(_args(mode="lockstep"))
    assert "--material random" in scripted_problem(_args(material="random"))
    assert "--episodes 0" in scripted_problem(_args(episodes=0))


@pytest.mark.parametrize("extra, needle", [
    (["--policy", "policies/rlc"], "--policy applies to the nodes only"),
    (["--mode", "lockstep", "--verbose"], "--mode, --verbose apply to the nodes only"),
    (["--episodes", "0"], "--scripted with --episodes 0"),
    (["--material", "random"], "--scripted with --material random"),
    (["--slopes", "15", "50"], "--slopes 50: outside the pile range"),
])
def test_scripted_refuses_what_it_cannot_honour(extra, needle, capsys):
    assert launcher_main(["--scripted", *extra], demo=True) == 2
    err = capsys.readouterr().err
    assert needle in err and err.count("\n") == 1, err


def test_scripted_runs_the_asked_episodes_and_slopes(capsys):
    """One attempt on each of two slopes (about a second of simulation): --episodes and --slopes
    reach the run, with the same attempts (seeds) the default demo runs first on those slopes."""
    assert launcher_main(["--scripted", "--episodes", "2", "--slopes", "20", "25", "--json"], demo=True) == 0
    rows = json.loads(capsys.readouterr().out)
    assert sorted(rows) == ["20", "25"]
    assert [rows[k]["episodes"] for k in ("20", "25")] == [1, 1]
    from lhd_sim_node.demo import run_scripted

    assert rows["20"]["aml"] == pytest.approx(run_scripted([20], 1)["20"]["aml"])
    assert launcher_main(["--scripted", "--episodes", "2", "--slope", "20", "--material", "nonhomogeneous"],
                         demo=True) == 0
    out = capsys.readouterr().out
    assert "nonhomogeneous material, 2 attempts (2 per slope)" in out
    assert [line.split()[0] for line in out.splitlines()[2:-1]] == ["20"]


def test_demo_help_shows_the_real_defaults_and_config_check_has_a_description():
    demo = subprocess.run(LHD + ["demo", "--help"], capture_output=True, text=True, timeout=60)
    assert demo.returncode == 0
    text = " ".join(demo.stdout.split())
    assert "(default: random)" not in text
    assert "default: 15 20 25 30" in text and "default 12: 3 per slope" in text
    cfg = subprocess.run(LHD + ["config", "check", "--help"], capture_output=True, text=True, timeout=60)
    assert cfg.returncode == 0
    assert "validate an lhd_params.yaml" in " ".join(cfg.stdout.split())
