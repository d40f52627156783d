"""The simulator benchmark runs, prints its figures, and its physics-only replay goes through
exactly the env's states (otherwise it would time different physics)."""
import json
import os
import subprocess
import sys

import pytest

from lhd_sim_node.bench import bench_sim

from rosutil import unique_domain_id


def test_bench_replays_the_same_physics():
    res = bench_sim(steps=150, rounds=1)
    assert res["replay_max_qpos_error"] == 0.0
    assert res["env_steps_per_s"] > 0 and res["physics_only_steps_per_s"] > 0
    # the ratio is computed from the unrounded rates; the printed rates are rounded to 0.1 step/s
    assert res["ratio"] == pytest.approx(res["env_steps_per_s"] / res["physics_only_steps_per_s"], abs=1.5e-3)
    assert res["substeps_per_control_step"] == 25 and res["fee_updates_per_control_step"] == 5


def test_lhd_bench_sim_json_cli():
    out = subprocess.run([sys.executable, "-m", "lhd_loading_ros.cli.main", "bench", "sim", "--json", "--steps", "100",
                          "--rounds", "1"], capture_output=True, text=True, check=True).stdout
    res = json.loads(out)
    assert {"env_steps_per_s", "physics_only_steps_per_s", "ratio"} <= set(res)


def test_lhd_config_check_cli(tmp_path):
    ok = subprocess.run([sys.executable, "-m", "lhd_loading_ros.cli.main", "config", "check"], capture_output=True, text=True)
    assert ok.returncode == 0 and ok.stdout.strip().endswith(": ok")
    bad = tmp_path / "bad.yaml"
    bad.write_text("paper: {}\n")
    res = subprocess.run([sys.executable, "-m", "lhd_loading_ros.cli.main", "config", "check", str(bad)],
                         capture_output=True, text=True)
    assert res.returncode == 1 and "missing key 'paper.ddpg'" in res.stderr


def test_lhd_mjcf_writes_a_model_mujoco_loads(tmp_path):
    import mujoco

    out = tmp_path / "lhd.xml"
    subprocess.run([sys.executable, "-m", "lhd_loading_ros.cli.main", "mjcf", "--out", str(out)], check=True,
                   capture_output=True)
    m = mujoco.MjModel.from_xml_path(str(out))
    assert m.nu == 5 and abs(sum(m.body_mass) - 121.0) < 1e-5  # 3 motor rotors of 1e-6 kg (mjcf.py: rear differential)


def test_lhd_bench_node_runs_and_leaves_no_temporary_folder(tmp_path):
    """The policy node against a real sim node process; the sim's log folder goes at exit."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = dict(os.environ, TMPDIR=str(tmp), ROS_DOMAIN_ID=str(unique_domain_id()))
    p = subprocess.run([sys.executable, "-m", "lhd_loading_ros.cli.main", "bench", "node", "--json", "--cycles", "20"],
                       capture_output=True, text=True, timeout=240, env=env)
    assert p.returncode == 0, p.stderr[-3000:]
    res = json.loads(p.stdout)
    assert res["cycles"] >= 20 and res["rate_hz"] == 10.0
    assert 0 < res["latency_p50_ms"] <= res["latency_p99_ms"]
    assert list(tmp.iterdir()) == []


def test_lhd_bench_train_jobs_projects_the_study(tmp_path, cfg):
    """Two processes timed at once (as a study runs its trials), randomised, with the behaviour
    cloning recipe's replay: the study's projection is its rounds (ceil(10 / 2) = 5) times one
    run's protocol."""
    import math

    import yaml

    cfg["training"].update({"learning_starts": 256, "demo_share": 0.2, "demo_bc": 1.0})
    path = tmp_path / "p.yaml"
    path.write_text(yaml.safe_dump(cfg))
    out = subprocess.run([sys.executable, "-m", "lhd_loading_ros.cli.main", "bench", "train", "--json", "--steps", "60",
                          "--jobs", "2", "--randomize", "--config", str(path)], capture_output=True, text=True,
                         check=True).stdout
    res = json.loads(out)
    assert res["jobs"] == 2 and res["randomize"] is True and res["steps"] == 60
    assert res["updates_per_s"] > 0 and res["env_steps_per_s"] > 0 and res["loop_steps_per_s"] > 0
    assert res["projected_study_min"] == pytest.approx(math.ceil(10 / 2) * res["projected_protocol_min"], abs=0.06)
    # the protocol's time is at least its 300,000 steps at the measured loop rate
    assert res["projected_protocol_min"] >= cfg["training"]["total_steps"] / res["loop_steps_per_s"] / 60 - 0.01


def test_lhd_bench_train_names_bad_input(tmp_path):
    def run(*extra):
        return subprocess.run([sys.executable, "-m", "lhd_loading_ros.cli.main", "bench", "train", "--steps", "10",
                               *extra], capture_output=True, text=True)

    r = run("--jobs", "0")
    assert r.returncode == 2 and "--jobs must be >= 1, got 0" in r.stderr
    bad = tmp_path / "bad.yaml"
    bad.write_text("paper: {}\n")
    r = run("--jobs", "2", "--config", str(bad))
    assert r.returncode == 2 and "lhd bench train:" in r.stderr and "Traceback" not in r.stderr
