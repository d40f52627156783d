"""Replays the bridge's drift detection on the bags of a `lhd up twin` run folder and scores it against the
simulator's own flags (/lhd/twin/truth/drift, the training's rule): the flags the bridge published (as recorded),
the flags the time-aligned window (lhd_hw_bridge.bridge_core.DriftWindow, the bridge since 2026-11-29) gives from
the same bag's /lhd/joint_states (integrated wheel angles at the frames' arrival: the bag has no device clock, which
the bridge itself uses through DeviceClock) and /lhd/odom (speed at the image's instant), with the motor currents of /lhd/hw/status (10 Hz) where the window has no answer, and the flags of the
bridge's earlier rule ("instant": each frame's wheel speeds against the newest /lhd/odom speed, or a motor current
over its preset). Per attempt, over its running
phase (first wheel command to the last truth sample): agreement with the truth at each truth sample (the latest
flag of each source at that instant, as `lhd up twin` scores it), and the flags in the first 0.5 s after the start.

Usage: .venv/bin/python docs/evidence/drift_window/replay_drift.py RUN_DIR"""
import glob
import sys
from pathlib import Path

from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from lhd_hw_bridge.bridge_core import BridgeParams, DriftWindow, detect_drift
from lhd_hw_bridge.protocol import SensorFrame
from lhd_loading_ros.task.config import load_config

import math

TOPICS = ("/lhd/cmd/auto", "/lhd/joint_states", "/lhd/odom", "/lhd/hw/status", "/lhd/wheel_drift/front",
          "/lhd/wheel_drift/rear", "/lhd/twin/truth/drift")


def stamp(m):
    return m.header.stamp.sec + m.header.stamp.nanosec * 1e-9


def instant_rule(vel, cur, v, p: BridgeParams) -> tuple[bool, bool]:
    """The bridge's rule until 2026-11-29 (bridge_core.detect_drift then): per wheel, its rim speed against
    the newest odometry speed, or a motor current over its no-drift preset."""
    def slips(omega):
        if v is None:
            return False
        rim = omega * p.wheel_radius
        return abs(rim - v[0]) > max(p.drift_min_speed, p.drift_slip_ratio * max(abs(rim), abs(v[0])))
    front = slips(vel[2]) or slips(vel[3]) or cur[0] > p.drift_current_front or cur[1] > p.drift_current_front
    rear = slips(vel[4]) or cur[2] > p.drift_current_rear
    return front, rear


def replay(bag: Path, p: BridgeParams) -> dict:
    ts = get_typestore(Stores.ROS2_JAZZY)
    win = DriftWindow(p.control_period)
    cur = (0.0, 0.0, 0.0)
    rec = {"front": False, "rear": False}
    new = (False, False)
    odom_arrival = None
    t_start = None
    scores = {"recorded": [0, 0], "window": [0, 0], "instant": [0, 0]}   # agreements front, rear
    n = 0
    start_flags = {"recorded": 0, "window": 0, "instant": 0, "truth": 0}
    start_n = {"recorded": 0, "window": 0, "instant": 0, "truth": 0}
    v_odom = None
    old = (False, False)
    with AnyReader([bag], default_typestore=ts) as r:
        conns = [c for c in r.connections if c.topic in TOPICS]
        for c, t, raw in r.messages(connections=conns):
            m = r.deserialize(raw, c.msgtype)
            tr = t * 1e-9
            if c.topic == "/lhd/cmd/auto":
                if t_start is None and m.data[0] > 0:
                    t_start = tr
            elif c.topic == "/lhd/odom":
                if win.add_odom(stamp(m), m.twist.twist.linear.x):
                    odom_arrival = tr
                if math.isfinite(m.twist.twist.linear.x):
                    v_odom = (m.twist.twist.linear.x, tr)
            elif c.topic == "/lhd/hw/status":
                kv = {k.key: k.value for k in m.values}
                try:
                    cur = (float(kv["current_fl_A"]), float(kv["current_fr_A"]), float(kv["current_rear_A"]))
                except (KeyError, ValueError):
                    pass
            elif c.topic == "/lhd/joint_states":
                a = m.position
                win.add_wheels(stamp(m), (a[2], a[3], 0.5 * (a[4] + a[5])), 0)
                fresh = odom_arrival is not None and tr - odom_arrival <= p.odom_timeout
                slip = win.slips(p) if fresh else None
                f = SensorFrame(0, 0, 0, 0, 0, 0, 0, 0, cur[0], cur[1], cur[2], 0, 0, 0)
                new = detect_drift(f, slip, p)
                old = instant_rule(m.velocity, cur, v_odom if v_odom and tr - v_odom[1] <= p.odom_timeout else None, p)
                if t_start is not None and tr - t_start <= 0.5:
                    for k, fl in (("window", new), ("instant", old)):
                        start_n[k] += 1
                        start_flags[k] += int(fl[0] or fl[1])
            elif c.topic in ("/lhd/wheel_drift/front", "/lhd/wheel_drift/rear"):
                side = "front" if c.topic.endswith("front") else "rear"
                rec[side] = bool(m.data)
                if t_start is not None and tr - t_start <= 0.5 and side == "front":
                    start_n["recorded"] += 1
                    start_flags["recorded"] += int(rec["front"] or rec["rear"])
            elif c.topic == "/lhd/twin/truth/drift" and t_start is not None:
                truth = (bool(m.data[0]), bool(m.data[1]))
                n += 1
                for k, (fr, re) in (("recorded", (rec["front"], rec["rear"])), ("window", new), ("instant", old)):
                    scores[k][0] += fr == truth[0]
                    scores[k][1] += re == truth[1]
                if tr - t_start <= 0.5:
                    start_n["truth"] += 1
                    start_flags["truth"] += int(truth[0] or truth[1])
    out = {"samples": n}
    for k in scores:
        out[f"{k}_agree_front"] = scores[k][0] / n if n else float("nan")
        out[f"{k}_agree_rear"] = scores[k][1] / n if n else float("nan")
    for k in start_flags:
        out[f"{k}_flagged_first_0.5s"] = start_flags[k] / start_n[k] if start_n[k] else float("nan")
    return out


def main() -> None:
    run = Path(sys.argv[1])
    p = BridgeParams.from_config(load_config(None))
    rows = []
    for b in sorted(glob.glob(str(run / "bags" / "attempt_*"))):
        rows.append((Path(b).name, replay(Path(b), p)))
    keys = ["samples", "recorded_agree_front", "recorded_agree_rear", "window_agree_front", "window_agree_rear",
            "instant_agree_front", "instant_agree_rear", "truth_flagged_first_0.5s", "recorded_flagged_first_0.5s",
            "window_flagged_first_0.5s", "instant_flagged_first_0.5s"]
    print("attempt " + " ".join(keys))
    for name, o in rows:
        print(name[-4:] + " " + " ".join(f"{o[k]:.2f}" if isinstance(o[k], float) else str(o[k]) for k in keys))
    for k in keys[1:]:
        vals = [o[k] for _, o in rows if o[k] == o[k]]
        print(f"mean {k}: {sum(vals) / len(vals):.3f}" if vals else f"mean {k}: -")


if __name__ == "__main__":
    main()
