# Table of the held-out evaluations (`lhd eval --policy P --episodes 120 --seed 2000000 --json [--stress placement]`,
# one JSON line each, with "name" and "condition" added) written by the device run of this folder's README.
# Run: python3 docs/evidence/tilt_penalty/summarize.py docs/evidence/tilt_penalty/evals.jsonl
import json, statistics, sys

rows = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
by = {}
for r in rows:
    by.setdefault(r["name"], {})[r["condition"]] = r
print("| actor | nominal success | ASL | AML kg | time s | largest tilt, mean (deg) | tilt > 5 deg | 30 deg piles: tilt > 5 deg / mean largest | placement corners success |")
print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
groups = {}
for name in sorted(by):
    n, p = by[name].get("nominal"), by[name].get("placement")
    s30 = n["by_slope"].get("30", {}) if n else {}
    print(f"| {name} | {n['success_rate']:.3f} | {n['asl']:.2f} | {n['aml']:.1f} | {n['elapsed_s']:.2f} | {n['max_tilt_deg']:.2f} | "
          f"{n['tilt_over_5deg_rate']:.3f} | {s30.get('tilt_over_5deg_rate', float('nan')):.2f} / {s30.get('max_tilt_deg', float('nan')):.2f} | "
          f"{p['success_rate']:.3f} |" if p else "| - |")
    g = name.rsplit("_s", 1)[0] if "_s" in name and name.rsplit("_s", 1)[1].isdigit() else None
    if g:
        groups.setdefault(g, []).append((n, p))
print()
for g, lst in groups.items():
    def ms(vals):
        return f"{statistics.mean(vals):.3f} +- {statistics.stdev(vals) if len(vals) > 1 else 0.0:.3f}"
    print(f"{g} ({len(lst)} seeds, final actors): nominal success {ms([n['success_rate'] for n, _ in lst])}, "
          f"ASL {ms([n['asl'] for n, _ in lst])}, tilt > 5 deg (30 deg piles) {ms([n['by_slope']['30']['tilt_over_5deg_rate'] for n, _ in lst])}, "
          f"largest tilt on 30 deg piles {ms([n['by_slope']['30']['max_tilt_deg'] for n, _ in lst])} deg, "
          f"placement success {ms([p['success_rate'] for _, p in lst])}")
