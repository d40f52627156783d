"""Training episodes on shallow piles (slope < 15 deg), by phase of training: the success share of the
actor's own episodes, of the scripted demonstrations', and the actor's mean load.

    .venv/bin/python docs/evidence/wide_demo_twin_sil/shallow_by_phase.py runs/<study>/rlc_dr*/seed_*/episodes.csv

Reads each run's episodes.csv (learning/train.py): one row per training episode, with its slope, driver
(actor or scripted crowd), the paper's success test and the load."""
import csv
import sys

PHASES = ((0, 50_000), (50_000, 100_000), (100_000, 150_000), (150_000, 200_000), (200_000, 250_000),
          (250_000, 300_001))


def main(paths):
    print("run | per phase of training (steps, thousands): actor's success / demonstrations' success / actor's "
          "mean load, n actor episodes")
    print("      " + "  ".join(f"{lo // 1000}-{min(hi, 300_000) // 1000}".center(26) for lo, hi in PHASES))
    for path in paths:
        with open(path) as f:
            rows = [r for r in csv.DictReader(f) if float(r["alpha_deg"]) < 15.0 and r["outcome"] != "aborted"]
        cells = []
        for lo, hi in PHASES:
            a = [r for r in rows if lo <= int(r["step"]) < hi and r["driver"] == "actor"]
            d = [r for r in rows if lo <= int(r["step"]) < hi and r["driver"] != "actor"]
            sa = sum(int(r["success"]) for r in a) / len(a) if a else float("nan")
            sd = sum(int(r["success"]) for r in d) / len(d) if d else float("nan")
            ml = sum(float(r["loaded"]) for r in a) / len(a) if a else float("nan")
            cells.append(f"{sa:.2f} / {sd:.2f} / {ml:4.1f} kg n={len(a):3d}")
        parts = path.split("/")
        print(f"{parts[-4]}/{parts[-3]}/{parts[-2]}: " + "  ".join(cells))


if __name__ == "__main__":
    main(sys.argv[1:])
