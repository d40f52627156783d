"""The held-out figures of one or more `lhd report --held-out --json` files, one line per condition:
success and ASL, mean +- sd over the seeds, and the seeds' own success (docs/training.md "A settling stage").
Usage: python3 docs/evidence/settle_stage/held_out_summary.py REPORT.json [...]"""
import json
import sys

for path in sys.argv[1:]:
    for name, d in json.load(open(path)).items():
        h = d["held_out"]
        print(f"== {name} ({len(h['runs'])} seeds, final steps {sorted(set(d['final_steps']))}, {h['episodes']} "
              f"episodes a condition, seed {h['seed']})")
        for cond, c in h["conditions"].items():
            s, a = c["success_rate"], c["asl"]
            print(f"  {cond:>11}: success {s['mean']:.3f} +- {s['sd']:.3f} (seeds {' / '.join(f'{v:.3f}' for v in s['values'])}),"
                  f" ASL {a['mean']:.2f} +- {a['sd']:.2f}")
