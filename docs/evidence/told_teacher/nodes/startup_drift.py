"""Per attempt of a `lhd up twin` / `lhd up real` run folder (its bags): when the first drift flag came
after the controller's first wheel command, how long that first run of flags lasted, and when the first
arm command came (s). Usage: python docs/evidence/told_teacher/nodes/startup_drift.py RUN_DIR"""
import sys, glob
from pathlib import Path
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore
ts = get_typestore(Stores.ROS2_JAZZY)
out=[]
for b in sorted(glob.glob(sys.argv[1] + "/bags/attempt_*")):
    with AnyReader([Path(b)], default_typestore=ts) as r:
        conns = [c for c in r.connections if c.topic in ("/lhd/cmd/auto", "/lhd/wheel_drift/front", "/lhd/wheel_drift/rear")]
        t_start=None; run_start=None; run_len=None; flags={"f":False,"r":False}; first_lift=None
        for c, t, raw in r.messages(connections=conns):
            m = r.deserialize(raw, c.msgtype)
            if c.topic == "/lhd/cmd/auto":
                if t_start is None and m.data[0] > 0: t_start = t
                if first_lift is None and t_start and (m.data[1] != 0 or m.data[2] != 0): first_lift=(t-t_start)/1e9
                continue
            if t_start is None: continue
            flags["f" if "front" in c.topic else "r"] = m.data
            d = flags["f"] or flags["r"]
            if run_len is None:
                if d and run_start is None: run_start = t
                if not d and run_start is not None: run_len = (t - run_start)/1e9
        out.append((Path(b).name[-4:], None if run_start is None else round((run_start-t_start)/1e9,2), run_len if run_len is None else round(run_len,2), first_lift and round(first_lift,2)))
for o in out: print(*o)
