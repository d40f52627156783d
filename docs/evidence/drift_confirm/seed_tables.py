"""The per-seed tables of a five-seed run side by side (2026-12-01): success of every slope of 10-40 deg (both materials)
and the slope-error sweep on 15 and 30 deg piles (success, mass change against the no-error figure), with the seeds'
mean (the seeds whose folders exist). Cells the nodes refuse (told outside the actor's 10-40 deg) are marked *. Run from the repository root:
    python3 docs/evidence/drift_confirm/seed_tables.py docs/evidence/drift_confirm/drift_confirm3_rld"""
import csv
import glob
import re
import statistics
import sys

prefix = sys.argv[1]
# the seeds evaluated (0-4 for a study; 5-9 for a replicate)
seeds = sorted(int(m.group(1)) for d in glob.glob(f"{prefix}_seed*/") if (m := re.search(r"_seed(\d+)/$", d)))
ctl = {s: list(csv.DictReader(open(f"{prefix}_seed{s}/table_controllers.csv"))) for s in seeds}
err = {s: list(csv.DictReader(open(f"{prefix}_seed{s}/table_slope_error.csv"))) for s in seeds}
print("every slope, success per seed (homogeneous / nonhomogeneous), 20 attempts a cell")
for i, r in enumerate(ctl[seeds[0]]):
    if r["slope_deg"] == "all":
        continue
    v = [float(ctl[s][i]["success_rate"]) for s in seeds]
    print(f"  {r['material']:15s} {float(r['slope_deg']):4.0f} deg  " + " ".join(f"{x:.2f}" for x in v)
          + f"  mean {statistics.mean(v):.2f}")
print("slope error: success per seed | mass change per seed [%] | mean mass change [%]")
for i, r in enumerate(err[seeds[0]]):
    told = float(r["told_deg"])
    mark = "*" if not 10.0 <= told <= 40.0 else " "
    sr = [float(err[s][i]["success_rate"]) for s in seeds]
    mc = [float(err[s][i]["mass_change_pct"]) for s in seeds]
    print(f"  {float(r['slope_deg']):4.0f} told {told:4.0f}{mark} " + " ".join(f"{x:.2f}" for x in sr) + " | "
          + " ".join(f"{x:+4.0f}" for x in mc) + f" | {statistics.mean(mc):+5.1f}")
