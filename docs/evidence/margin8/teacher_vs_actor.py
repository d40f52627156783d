"""r_success and the mean load of the demonstrations (the scripted teacher) and of the actor's own episodes
(with its exploration noise) per slope band, after step 100,000, from each seed's episodes.csv of a run.

    python3 docs/evidence/margin8/teacher_vs_actor.py runs/RUN [--after 100000]

Written for the thirty-fourth session (2026-12-02, docs/training.md "A slope the LiDAR mostly gets right"): where the
teacher earns the reward and the actor does not, and the other way round."""
import argparse
import csv
import glob
import os

BANDS = ((10.0, 12.5), (12.5, 15.0), (15.0, 20.0), (20.0, 30.0), (30.0, 40.01))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run")
    ap.add_argument("--after", type=int, default=100_000, help="count episodes that start after this step")
    a = ap.parse_args()
    seeds = sorted(glob.glob(os.path.join(a.run, "seed_*", "episodes.csv")))
    if not seeds:
        raise SystemExit(f"no seed_*/episodes.csv under {a.run}")
    print(f"{a.run}: episodes after step {a.after:,}; r_success share / mean load [kg] / episodes, "
          "teacher (demonstrations) | actor (its own, with exploration noise)")
    print("seed    " + "  ".join(f"{lo:g}-{min(hi, 40):g} deg".center(31) for lo, hi in BANDS))
    for path in seeds:
        rows = [r for r in csv.DictReader(open(path)) if int(r["step"]) > a.after]
        cells = []
        for lo, hi in BANDS:
            band = [r for r in rows if lo <= float(r["alpha_deg"]) < hi]
            out = []
            for scripted in (True, False):
                rs = [r for r in band if r["driver"].startswith("scripted") == scripted]
                n = max(1, len(rs))
                ok = sum(float(r["r_success"]) > 0.0 for r in rs) / n
                kg = sum(float(r["loaded"]) for r in rs) / n
                out.append(f"{ok:.2f}/{kg:2.0f}/{len(rs):4d}")
            cells.append(" | ".join(out))
        print(f"{os.path.basename(os.path.dirname(path)):8s}" + "  ".join(cells))


if __name__ == "__main__":
    main()
