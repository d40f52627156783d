"""table.md of evaluate.sh: success and loaded mass with the pile's zones -> the end-zone node's."""
import json
import sys
from pathlib import Path

d = Path(sys.argv[1])
actors = ["rld_machine", "rld_gains", "rld_told_teacher", "rlc_gains", "rld", "rlc"]
conds = ["nominal", "light", "dense", "rocky", "cohesive", "machine", "dense_placement", "randomized"]
print("success (AML kg), the pile's zones -> the end-zone node's at 1,880 kg/m^3; 120 held-out episodes, seed 2,000,000\n")
print("| condition | " + " | ".join(f"`{a}`" for a in actors) + " |")
print("|---|" + "---|" * len(actors))
for c in conds:
    cells = []
    for a in actors:
        p, n = (json.loads((d / f"{a}.{c}.{z}.json").read_text()) for z in ("pile", "end-zone-node"))
        cells.append(f"{p['success_rate']:.3f} ({p['aml']:.1f}) -> {n['success_rate']:.3f} ({n['aml']:.1f})")
    print(f"| {c} | " + " | ".join(cells) + " |")
print("\nsuccess on 15 deg piles, the same way\n")
print("| condition | " + " | ".join(f"`{a}`" for a in actors) + " |")
print("|---|" + "---|" * len(actors))
for c in conds:
    cells = []
    for a in actors:
        p, n = (json.loads((d / f"{a}.{c}.{z}.json").read_text()) for z in ("pile", "end-zone-node"))
        cells.append(f"{p['by_slope']['15']['success_rate']:.2f} -> {n['by_slope']['15']['success_rate']:.2f}")
    print(f"| {c} | " + " | ".join(cells) + " |")
