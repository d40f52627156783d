# Where the twin's v_x error comes from, offline from a `lhd up twin` run folder's bags: the Kalman
# filter replayed on the ArUco node's marker positions with other q and r; the same filter on the TRUE x at
# the image stamps (a perfect camera); the node's v_x against the instantaneous and the frame-mean truth.
# Run: .venv/bin/python docs/evidence/twin/vx_error_replay.py runs/twin/<run folder>
import glob, math, sys
import numpy as np
from pathlib import Path
from rosbags.highlevel import AnyReader
from lhd_loading_ros.perception.aruco import KalmanVelocityEstimator

run = sys.argv[1]
def load(b):
    meas, truth, odom = [], [], []
    with AnyReader([Path(b)]) as r:
        conns = [c for c in r.connections if c.topic in ("/lhd/aruco/marker_pose", "/lhd/twin/truth/odom", "/lhd/odom")]
        for c, t, raw in r.messages(connections=conns):
            m = r.deserialize(raw, c.msgtype)
            st = m.header.stamp.sec + m.header.stamp.nanosec * 1e-9
            if c.topic == "/lhd/aruco/marker_pose":
                meas.append((st, m.pose.position.x))
            elif c.topic == "/lhd/odom":
                odom.append((st, m.twist.twist.linear.x))
            else:
                truth.append((st, m.twist.twist.linear.x, m.pose.pose.position.x))
    return np.array(meas), np.array(truth), np.array(odom)

bags = sorted(glob.glob(f"{run}/bags/attempt_*"))
data = [load(b) for b in bags]
def score(q, rpos, lag=0.0):
    tot, n = 0.0, 0
    per = []
    for meas, truth, odom in data:
        kf = KalmanVelocityEstimator(q, rpos, max_gap=0.5)
        errs = []
        # running phase: stamps within the odom range of the stack (the attempt)
        t0, t1 = odom[0, 0], odom[-1, 0]
        for t, x in meas:
            kf.add(t, x)
            v = kf.velocity()
            if v is None or t < t0 or t > t1:
                continue
            vt = np.interp(t - lag, truth[:, 0], truth[:, 1])
            errs.append(v - vt)
        e = np.array(errs)
        per.append(math.sqrt(np.mean(e ** 2)))
        tot += float(np.sum(e ** 2)); n += len(e)
    return math.sqrt(tot / n), max(per), per

for q in (0.3, 1.0, 3.0, 10.0):
    for r in (0.0005, 0.001):
        pooled, worst, per = score(q, r)
        print(f"q {q:5.1f} r {r*1000:.1f} mm: pooled {pooled:.4f} worst {worst:.4f}")
# what the node published, for reference
tot = n = 0
for meas, truth, odom in data:
    vt = np.interp(odom[:, 0], truth[:, 0], truth[:, 1]); e = odom[:, 1] - vt
    tot += float(np.sum(e ** 2)); n += len(e)
print("node's /lhd/odom pooled", math.sqrt(tot / n))
print("--- per attempt: RMS of (finite-difference of truth x over 0.1 s) - truth v_x; and Kalman on TRUE x samples at the image stamps")
for k, (meas, truth, odom) in enumerate(data):
    t0, t1 = odom[0, 0], odom[-1, 0]
    sel = (truth[:, 0] >= t0) & (truth[:, 0] <= t1)
    tt, vv, xx = truth[sel, 0], truth[sel, 1], truth[sel, 2]
    # central difference over +-0.05 s
    vd = (np.interp(tt + 0.05, truth[:, 0], truth[:, 2]) - np.interp(tt - 0.05, truth[:, 0], truth[:, 2])) / 0.1
    e1 = math.sqrt(np.mean((vd - vv) ** 2))
    # Kalman on the true x at the image stamps (a perfect camera)
    kf = KalmanVelocityEstimator(1.0, 0.0005, max_gap=0.5)
    errs = []
    for t, _ in meas:
        kf.add(t, float(np.interp(t, truth[:, 0], truth[:, 2])))
        v = kf.velocity()
        if v is None or t < t0 or t > t1: continue
        errs.append(v - np.interp(t, truth[:, 0], truth[:, 1]))
    # measurement error of x: marker-derived x (+0.10 offset) vs truth x
    xe = [x + 0.10 - np.interp(t, truth[:, 0], truth[:, 2]) for t, x in meas if t0 <= t <= t1]
    print(f"att {k+1}: fd-vs-qvel {e1:.4f}; KF on true x {math.sqrt(np.mean(np.square(errs))):.4f}; x meas err sd {1000*np.std(xe):.2f} mm, mean {1000*np.mean(xe):.2f} mm; truth rate {len(tt)/(tt[-1]-tt[0]):.0f} Hz")
print("--- the node's /lhd/odom v_x against: instantaneous truth, truth's mean speed over one frame interval (1/30 s) centred, over 0.1 s")
P = {"inst": [0, 0], "frame": [0, 0], "0.1s": [0, 0]}
for k, (meas, truth, odom) in enumerate(data):
    t = odom[:, 0]; v = odom[:, 1]
    vi = np.interp(t, truth[:, 0], truth[:, 1])
    def mean_speed(h):
        return (np.interp(t + h, truth[:, 0], truth[:, 2]) - np.interp(t - h, truth[:, 0], truth[:, 2])) / (2 * h)
    vf, v1 = mean_speed(1 / 60), mean_speed(0.05)
    row = []
    for name, ref in (("inst", vi), ("frame", vf), ("0.1s", v1)):
        e = v - ref
        P[name][0] += float(np.sum(e ** 2)); P[name][1] += len(e)
        row.append(f"{name} {math.sqrt(np.mean(e ** 2)):.4f}")
    print(f"att {k+1}: " + ", ".join(row))
print("pooled: " + ", ".join(f"{k} {math.sqrt(a / n):.4f}" for k, (a, n) in P.items()))
