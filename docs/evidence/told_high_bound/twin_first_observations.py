# The drift flag and v_x of the first four observations of every attempt in twin runs (attempts.csv beside the bags):
#   .venv/bin/python docs/evidence/told_high_bound/twin_first_observations.py RUN_DIR... (runs of `lhd up twin --run-dir RUN_DIR`)
import sys, numpy as np, csv
from rosbags.highlevel import AnyReader
from pathlib import Path
for run in sys.argv[1:]:
    rows={int(r["attempt"]):r for r in csv.DictReader(open(f"{run}/attempts.csv"))}
    for b in sorted(Path(run,"bags").iterdir()):
        obs=[]
        with AnyReader([b]) as r:
            cs=[c for c in r.connections if c.topic=='/lhd/observation']
            for c,t,raw in r.messages(connections=cs): obs.append(np.asarray(r.deserialize(raw,c.msgtype).data))
        n=int(b.name.split('_')[1]); row=rows.get(n,{})
        print(Path(run).name, b.name, "slope", row.get("slope_deg"), row.get("outcome"), row.get("mass_kg"), "drift flag, first 4 obs:", [int(o[5]) for o in obs[:4]], "v_x:", [round(float(o[4]),2) for o in obs[:4]])
