"""The bridge's drift window (lhd_hw_bridge.bridge_core.DriftWindow) on a start from rest, against the simulator's
rule: the machine's coordinates from the simulator (a start from rest, full wheels, arm still; 20 ms chunks,
linear between them, 0.5 s standing before the arming), the marker's x at 30 images/s with the twin's 0.26 mm
noise through the ArUco node's Kalman filter as shipped (KalmanVelocityEstimator, accel_noise 1, position_noise
0.5 mm), each image at its own instant (no latency: the window's own error, not its lag), the wheels' angles at
90 Hz (the rear the differential's mean). Prints the instants of the first 0.4 s where the simulator's rule
(drift_flag(0) at each chunk: the twin's ground truth) and the bridge's window flag each axle.
Run from the repository root:
    .venv/bin/python docs/evidence/drift_lag/bridge_window_start.py > docs/evidence/drift_lag/bridge_window_start.txt"""
import math, numpy as np
from lhd_hw_bridge.bridge_core import BridgeParams, DriftWindow
from lhd_loading_ros.perception.aruco import KalmanVelocityEstimator
from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.task.randomization import Conditions
from lhd_sim_node.simulator import LhdSimulator
cfg = load_config(None)
p = BridgeParams.from_config(cfg)
for slope in (15.0, 30.0):
  for seed in range(3):
    sim = LhdSimulator(cfg)
    sim.reset(np.random.default_rng(seed), conditions=Conditions(rest_start=True, drift_flag_lag_max_s=0.2),
              alpha=math.radians(slope), material="homogeneous", d_attack=0.15, attack_speed=2.7)
    t0 = sim.data.time
    rec = [(0.0, float(sim.data.qpos[0]), *[float(sim.data.qpos[i]) for i in sim._wheel_qs])]
    truth = []
    for ch in range(50):
        sim.advance(np.array([sim.p.wheels_max, 0, 0]))
        rec.append((sim.data.time - t0, float(sim.data.qpos[0]), *[float(sim.data.qpos[i]) for i in sim._wheel_qs]))
        truth.append((rec[-1][0], sim.drift_flag(0)))
    rec = np.array(rec)
    # pad 0.5 s of standing before the arming
    pre = np.array([(-0.5 + k * 0.02, *rec[0, 1:]) for k in range(25)])
    R = np.vstack([pre, rec])
    X = lambda t: np.interp(t, R[:, 0], R[:, 1])
    W = lambda t: [np.interp(t, R[:, 0], R[:, 2 + k]) for k in range(4)]
    rng = np.random.default_rng(seed)
    kf = KalmanVelocityEstimator(accel_noise=1.0, position_noise=0.0005)
    w = DriftWindow(p.control_period)
    out = []
    for k in range(int(1.5 * 90)):
        tw = -0.5 + k / 90
        ang = W(tw)
        w.add_wheels(tw, (ang[0], ang[1], 0.5 * (ang[2] + ang[3])), 0)
        if k % 3 == 0:
            ti = tw
            kf.add(ti, X(ti) + rng.normal(0, 0.00026))
            v = kf.velocity()
            if v is not None:
                w.add_odom(ti, v)
        s = w.slips(p)
        if s is not None and -0.05 < tw < 0.5:
            out.append((round(tw, 3), int(s[0]), int(s[1])))
    tflags = [(round(t, 2), int(f), int(r)) for t, (f, r) in truth[:20]]
    print(slope, seed, "truth (t, front, rear) up:", [x for x in tflags if x[1] or x[2]])
    print("   bridge window (images at their instant, no latency) up:", [x for x in out if x[1] or x[2]][:12])
