"""How often the bridge's drift window (lhd_hw_bridge.bridge_core.DriftWindow) flags a wheel that rolls without
slip, when the machine's speed comes from the ArUco node's Kalman filter on a noisy marker position: 200 s at 30
images/s, the marker's x with white noise of sd sigma, perfect rolling wheels (frames at 90 Hz), a machine that
stands (v 0) or drives at 0.3 m/s. `shipped`: the filter's velocity_position_noise as shipped (0.5 mm, twice the
twin's 0.26 mm); `matched`: set to sigma (what docs/perception.md asks for a real camera).
Usage: .venv/bin/python docs/evidence/drift_window/noise_false_drift.py shipped|matched"""
import sys

import numpy as np

from lhd_hw_bridge.bridge_core import BridgeParams, DriftWindow
from lhd_loading_ros.perception.aruco import KalmanVelocityEstimator
from lhd_loading_ros.task.config import load_config

TUNE = sys.argv[1]
p = BridgeParams.from_config(load_config(None))
rng = np.random.default_rng(0)
for sigma in (0.00026, 0.001, 0.002, 0.0036):
    for v_true in (0.0, 0.3):
        kf = KalmanVelocityEstimator(accel_noise=1.0, position_noise=0.0005 if TUNE == "shipped" else max(0.0005, sigma))
        w = DriftWindow(p.control_period)
        flags = n = 0
        for k in range(30 * 200):
            t = k / 30
            kf.add(t, v_true * t + rng.normal(0, sigma))
            v = kf.velocity()
            if v is not None:
                w.add_odom(t, v)
            for m in range(3):
                tw = t + m / 90
                w.add_wheels(tw, (v_true * tw / p.wheel_radius,) * 3, 0)
            if k > 60:
                s = w.slips(p)
                if s is not None:
                    n += 1
                    flags += s[0]
        print(f"marker x noise sd {sigma * 1000:.2f} mm, machine at {v_true} m/s: false drift in {flags / n:.1%} of "
              f"{n} windows")
