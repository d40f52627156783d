"""`lhd bench twin`: the camera -> serial-line latency through the real stack against the twin
(a short run over real DDS, processes and a pty), and its matching of decisions to frames by hand."""
import json
import math
import os
import subprocess
import sys

import pytest

from lhd_loading_ros.cli.bench_twin import WHEEL_SCALE, match_decisions, summary, wheel_key
from rosutil import unique_domain_id

# a whole stack in real time: alone, in `make test-stack` (test/conftest.py)
SERIAL = True

KEYS = ("latency_p50_ms", "latency_p99_ms", "latency_max_ms", "camera_to_decision_p50_ms", "camera_to_decision_p99_ms",
        "decision_to_serial_p50_ms", "decision_to_serial_p99_ms")


@pytest.mark.parametrize("argv, expected", [
    (["--imu", "500"], "--imu 500: expected an IMU rate in [1, 200] Hz"),
    (["--imu", "0.5"], "--imu 0.5: expected an IMU rate in [1, 200] Hz"),
    (["--duration", "0"], "--duration must be a positive number of seconds"),
    (["--duration", "nan"], "--duration must be a positive number of seconds"),
    (["--duration", "inf"], "--duration must be a positive number of seconds"),
    (["--timeout", "-5"], "--timeout must be a positive number of seconds"),
    # the machine's RLD and its own file, as lhd up real runs them (cli/up_real.machine_actor)
    (["--slopes", "100"], "--slopes 100: outside the pile range [10, 40] deg of "
                          + os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))),
                                         "policies", "rld_drift_confirm_margin8", "lhd_params.yaml")),
    (["--slopes", "abc"], "--slopes 'abc': expected degrees, e.g. 20 or '15,30'"),
    (["--no-imu", "--imu", "100"], "not allowed with argument"),
])
def test_bad_arguments_are_refused_before_anything_starts(argv, expected, capsys):
    from lhd_loading_ros.cli.bench_twin import main

    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    assert expected in capsys.readouterr().err


def test_wheel_key_clamps_and_rounds_like_the_wire():
    assert wheel_key(1.23449, 2.7) == 1234            # 1 mrad/s counts
    assert wheel_key(-0.4, 2.7) == 0                  # no reverse
    assert wheel_key(3.5, 2.7) == 2700                # clamped to wheels_max
    assert WHEEL_SCALE == 1e-3


def test_matching_by_hand():
    s = 1_000_000_000
    # stamps (wall, ns) and publication times (monotonic, ns); frames (wall s, mono s, wheel)
    dec = [dict(odom_stamp_ns=100 * s, mono_ns=10 * s, u_wheels=1.0, why="odom"),
           dict(odom_stamp_ns=101 * s, mono_ns=11 * s, u_wheels=1.0, why="odom"),       # same set-point: not counted
           dict(odom_stamp_ns=0, mono_ns=12 * s, u_wheels=0.0, why="fallback"),       # fallback: apart
           dict(odom_stamp_ns=103 * s, mono_ns=13 * s, u_wheels=2.0, why="odom"),
           dict(odom_stamp_ns=104 * s, mono_ns=14 * s, u_wheels=2.5, why="odom")]     # no frame: unmatched
    frames = [(100.030, 9.99, 0.5),          # before the first decision: not it
              (100.040, 10.010, 0.5),        # after it, but another set-point (the previous command)
              (100.052, 10.022, 1.0),        # the first decision's frame: 52 ms after its image
              (100.070, 10.040, 1.0),
              (103.031, 13.020, 2.0),        # the fourth decision's: 31 ms
              (104.9, 14.9, 2.0)]            # 2.5 never comes within 0.5 s
    m = match_decisions(dec, frames, 2.7)
    assert m["total"] == pytest.approx([52.0, 31.0], abs=1e-3)
    assert m["to_serial"] == pytest.approx([22.0, 20.0], abs=1e-3)
    assert (m["unchanged"], m["fallback"], m["unmatched"], m["decisions"], m["frames"]) == (1, 1, 1, 5, 6)
    r = summary(m)
    assert r["n"] == 2 and r["latency_max_ms"] == pytest.approx(52.0, abs=1e-3)
    assert r["latency_p50_ms"] == pytest.approx(41.5, abs=1e-3)        # the mean of two
    assert r["latency_p99_ms"] == pytest.approx(31.0 + 0.99 * 21.0, abs=1e-3)   # numpy's linear interpolation


def test_bench_twin_short_run_prints_finite_positive_figures(tmp_path):
    env = dict(os.environ, ROS_DOMAIN_ID=str(unique_domain_id()), PYTHONUNBUFFERED="1")
    proc = subprocess.run([sys.executable, "-m", "lhd_loading_ros.cli.bench_twin", "--duration", "6", "--json",
                           "--log-dir", str(tmp_path / "logs"), "--timeout", "90"],
                          capture_output=True, text=True, timeout=150, env=env)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    lines = proc.stdout.strip().splitlines()
    assert "latency" in proc.stdout and "p99" in proc.stdout
    r = json.loads(lines[-1])
    for k in KEYS:
        assert math.isfinite(r[k]) and r[k] > 0, (k, r)
    assert r["latency_p50_ms"] <= r["latency_p99_ms"] <= r["latency_max_ms"]
    assert isinstance(r["n"], int) and r["n"] >= 1, r
    assert r["n"] + r["unchanged"] + r["unmatched"] + r["fallback"] == r["decisions"]
    # the two halves add up to the whole for each decision, so their medians cannot both exceed it
    assert r["camera_to_decision_p50_ms"] < r["latency_max_ms"] and r["decision_to_serial_p50_ms"] < r["latency_max_ms"]
    assert r["command_frames"] > r["decisions"]          # the bridge's 50 Hz stream carries the 10 Hz decisions
    assert r["attempts"] >= 1
