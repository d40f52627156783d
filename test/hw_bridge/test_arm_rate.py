"""The Due's joint rates over a window (firmware arm_rate.h) and the Python twin of it
(task/arm_sensors.RateWindow, which the digital twin's device and the environment use): hand-computed
cases, and both implementations on the same irregular, noisy samples."""
from __future__ import annotations

import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from lhd_loading_ros.task.arm_sensors import RATE_WINDOW_S, RateWindow, quantize

FIRMWARE = Path(__file__).resolve().parents[2] / "lhd_hw_bridge" / "lhd_hw_bridge" / "firmware" / "lhd_due"


def test_a_ramp_reads_its_slope_from_the_first_window_on():
    w = RateWindow(0.1)
    assert w.push(0.0, 0.3) == 0.0                      # one sample: no rate yet
    # 0.2 rad/s sampled every 10 ms: every difference is the slope, over a growing span first
    for k in range(1, 30):
        assert w.push(0.01 * k, 0.3 + 0.2 * 0.01 * k) == pytest.approx(0.2, rel=1e-9)


def test_the_window_is_the_difference_over_exactly_its_length():
    w = RateWindow(0.1)
    ts = [0.01 * k for k in range(40)]
    angles = [0.0 if t < 0.2 else 0.19 * (t - 0.2) for t in ts]   # the valve opens at 0.2 s
    rates = [w.push(t, a) for t, a in zip(ts, angles)]
    for k, (t, r) in enumerate(zip(ts, rates)):
        if k >= 10:                                      # a full window behind it: (a(t) - a(t - 0.1)) / 0.1
            back = angles[k - 10]
            assert r == pytest.approx((angles[k] - back) / 0.1, abs=1e-12), t
    # the lag a window costs: half way up 50 ms after the valve opened, full speed from 0.1 s on
    assert rates[25] == pytest.approx(0.19 * 0.05 / 0.1) and rates[31] == pytest.approx(0.19)


def test_noise_shrinks_with_the_window_as_sqrt2_sd_over_it():
    rng = np.random.default_rng(3)
    sd = math.radians(0.1)
    for window, frame in ((0.01, 0.01), (0.1, 0.01)):
        w = RateWindow(window)
        rates = [w.push(frame * k, float(rng.normal(0.0, sd))) for k in range(20000)][100:]
        assert np.std(rates) == pytest.approx(math.sqrt(2) * sd / window, rel=0.05), window


def test_quantize_reads_the_nearest_count():
    q = math.tau / 4096
    assert quantize(0.0, 4096) == 0.0 and quantize(0.4 * q, 4096) == 0.0 and quantize(0.6 * q, 4096) == q
    assert quantize(-2.6 * q, 4096) == pytest.approx(-3 * q) and quantize(0.123, 0) == 0.123


def test_bad_windows_and_samples_out_of_order_are_refused():
    for bad in (0.0, -0.1, float("nan")):
        with pytest.raises(ValueError, match="rate window"):
            RateWindow(bad)
    w = RateWindow()
    w.push(1.0, 0.0)
    with pytest.raises(ValueError, match="not after"):
        w.push(1.0, 0.1)


def test_firmware_and_python_give_the_same_rates(tmp_path):
    if shutil.which("g++") is None:
        pytest.skip("no C++ compiler on this machine")
    exe = tmp_path / "arm_rate"
    here = Path(__file__).parent / "firmware_host"
    subprocess.run(["g++", "-std=c++17", "-O1", "-Wall", "-Wextra", "-Werror", f"-I{FIRMWARE}",
                    str(here / "arm_rate_main.cpp"), "-o", str(exe)], check=True)
    rng = np.random.default_rng(7)
    # 10 ms frames with jitter (the Due's loop), a boom lifting, stopping and lifting, with 0.1 deg noise;
    # the clock starts near its 32-bit wrap, as micros() does after 71 minutes
    t_us = (2**32 - 300_000 + np.cumsum(rng.integers(9_000, 12_000, 400))) % 2**32
    angle = np.cumsum(np.where((np.arange(400) // 60) % 2 == 0, -0.0019, 0.0)) + rng.normal(0, math.radians(0.1), 400)
    angle = angle.astype(np.float32)
    lines = "".join(f"{int(t)} {a:.9g}\n" for t, a in zip(t_us, angle))
    out = subprocess.run([str(exe)], input=lines, capture_output=True, text=True, check=True).stdout.split()
    c_rates = np.array([float(v) for v in out])
    w = RateWindow(RATE_WINDOW_S)
    t_unwrapped = np.concatenate([[t_us[0]], t_us[0] + np.cumsum((np.diff(t_us.astype(np.int64))) % 2**32)])
    py_rates = np.array([w.push(float(t) * 1e-6, float(a)) for t, a in zip(t_unwrapped, angle)])
    assert len(c_rates) == 400
    np.testing.assert_allclose(c_rates, py_rates, atol=2e-4)   # float32 on the device
    assert np.abs(py_rates).max() > 0.1                        # the lifts are in it
