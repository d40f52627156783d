# The camera + accelerometer speed filter (perception.aruco.InertialVelocityEstimator) replayed offline on
# `lhd up twin --imu` run folders: the ArUco node's base_link x (/lhd/odom) and the IMU's accelerations
# (/lhd/imu, turned into the pile frame's x as the node does), scored against the twin's truth v_x from the
# attempt's start (as `lhd up twin` scores). Each image is filtered with the IMU samples the recorder had
# received CUT seconds before the image's odometry arrived (CUT = -0.1: every sample, the ideal order;
# about 0.015 reproduces what the node had). Run:
#   .venv/bin/python docs/evidence/twin/vx_accel_replay.py runs/twin/<run> [runs/twin/<run> ...]
import math, sys
from pathlib import Path
import numpy as np
from rosbags.highlevel import AnyReader
from lhd_loading_ros.perception.aruco import InertialVelocityEstimator, forward_acceleration, roll_pitch

def load(bag):
    ev, truth, run = [], [], []
    topics = ("/lhd/imu", "/lhd/twin/truth/odom", "/lhd/odom", "/lhd/episode")
    with AnyReader([bag]) as r:
        for c, t, raw in r.messages(connections=[c for c in r.connections if c.topic in topics]):
            m = r.deserialize(raw, c.msgtype)
            if c.topic == "/lhd/episode":
                if m.message == "running" and not run:
                    run.append(t * 1e-9)
                continue
            s = m.header.stamp.sec + m.header.stamp.nanosec * 1e-9
            if c.topic == "/lhd/imu" and m.linear_acceleration_covariance[0] != -1.0:
                la, o = m.linear_acceleration, m.orientation
                ro, pi = roll_pitch(o.x, o.y, o.z, o.w)
                ev.append((t * 1e-9, 0, s, forward_acceleration((la.x, la.y, la.z), ro, pi, 0.0)))
            elif c.topic == "/lhd/odom":
                ev.append((t * 1e-9, 1, s, m.pose.pose.position.x, m.twist.twist.linear.x))
            elif c.topic == "/lhd/twin/truth/odom":
                truth.append((s, m.twist.twist.linear.x))
    truth = np.array(truth)
    truth = truth[np.concatenate([[True], np.diff(truth[:, 0]) > 1e-6])]
    return ev, truth, run[0]

data = [load(b) for run in sys.argv[1:] for b in sorted(Path(run).glob("bags/attempt_*"))]

def rms(e):
    return math.sqrt(float(np.mean(np.square(e))))

def score(cut, hold=0.02, qa=0.01, q=1.0):
    pooled, per = [], []
    for ev, truth, t0 in data:
        est = InertialVelocityEstimator(q, 0.0005, 0.5, imu_accel_noise=qa, accel_timeout=0.2, hold=hold)
        errs = []
        for e in sorted([(e[0] - (cut if e[1] == 1 else 0.0),) + e[1:] for e in ev]):
            if e[1] == 0:
                est.add_accel(e[2], e[3])
                continue
            est.add(e[2], e[3])
            v = est.velocity()
            if v is not None and e[2] >= t0:
                errs.append(v - float(np.interp(e[2], truth[:, 0], truth[:, 1])))
        pooled += errs
        per.append(rms(errs))
    return rms(pooled), max(per)

node = [rms([e[4] - float(np.interp(e[2], tr[:, 0], tr[:, 1])) for e in ev if e[1] == 1 and e[2] >= t0])
        for ev, tr, t0 in data]
print(f"{len(data)} attempts; the node's own v_x: per-attempt RMS worst {max(node):.4f}, mean {np.mean(node):.4f} m/s")
for cut in (-0.1, 0.0, 0.015, 0.025):
    for hold in (0.0, 0.02, 0.2):
        p, w = score(cut, hold)
        print(f"cut {cut:+.3f} s, hold {hold:.2f} s: pooled {p:.4f}, worst attempt {w:.4f} m/s")
