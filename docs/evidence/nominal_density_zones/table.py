"""table.md of evaluate.sh: success and loaded mass with the pile's zones -> the end-zone node's."""
import json
import sys
from pathlib import Path

d = Path(sys.argv[1])
actors = ["rld_machine", "rld_gains", "rld_told_teacher", "rlc_gains", "rld", "rlc"]
conds = ["nominal", "light", "dense", "rocky", "cohesive", "machine", "dense_placement", "randomized"]


def table(title, cell):
    """One row per condition, one column per actor; cell(pile_result, node_result) -> text."""
    print(title + "\n")
    print("| condition | " + " | ".join(f"`{a}`" for a in actors) + " |")
    print("|---|" + "---|" * len(actors))
    for c in conds:
        cells = [cell(*(json.loads((d / f"{a}.{c}.{z}.json").read_text()) for z in ("pile", "end-zone-node")))
                 for a in actors]
        print(f"| {c} | " + " | ".join(cells) + " |")


table("success (AML kg), the pile's zones -> the end-zone node's at 1,880 kg/m^3; 120 held-out episodes, seed 2,000,000",
      lambda p, n: f"{p['success_rate']:.3f} ({p['aml']:.1f}) -> {n['success_rate']:.3f} ({n['aml']:.1f})")
print()
table("success on 15 deg piles, the same way",
      lambda p, n: f"{p['by_slope']['15']['success_rate']:.2f} -> {n['by_slope']['15']['success_rate']:.2f}")
