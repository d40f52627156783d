"""Who earns r_success where, in training: the scripted teacher's demonstrations against the actor's own
episodes, by the pile's slope band, from each seed's episodes.csv (the episodes that started after step
150,000, once the actors have learned what they will).

    python3 docs/evidence/demo_failing/teacher_vs_actor.py runs/steep_rlc_reward_test [runs/... ...]

Columns: n (episodes), paper (the paper's success test), r_succ (r_success paid: the test with the
training's 4 kg mass margin and pitch margin), kg (mean load). Reads only the CSV (no simulator).
"""
import csv
import sys

BANDS = ((10.0, 12.5), (12.5, 15.0), (15.0, 20.0), (20.0, 40.01))
FROM_STEP = 150_000


def rows_of(path):
    with open(path) as f:
        return [r for r in csv.DictReader(f) if r["outcome"] != "aborted" and int(r["step"]) > FROM_STEP]


def main(runs):
    for run in runs:
        for s in range(10):
            try:
                rows = rows_of(f"{run}/seed_{s}/episodes.csv")
            except FileNotFoundError:
                continue
            print(f"{run} seed {s}")
            print(f"  {'slope, deg':<11} {'driver':<8} {'n':>5} {'paper':>6} {'r_succ':>7} {'kg':>6}")
            for lo, hi in BANDS:
                for drv in ("scripted", "actor"):
                    sel = [r for r in rows if lo <= float(r["alpha_deg"]) < hi and r["driver"].startswith(drv)]
                    if not sel:
                        continue
                    n = len(sel)
                    ok = sum(int(r["success"]) for r in sel) / n
                    rs = sum(float(r["r_success"] or 0) > 0 for r in sel) / n
                    kg = sum(float(r["loaded"]) for r in sel) / n
                    band = f"{lo:g}-{min(hi, 40):g}"
                    print(f"  {band:<11} {'teacher' if drv == 'scripted' else 'actor':<8} {n:5d} {ok:6.2f} {rs:7.2f} {kg:6.1f}")


if __name__ == "__main__":
    main(sys.argv[1:] or ["runs/steep_rlc_reward_test"])
