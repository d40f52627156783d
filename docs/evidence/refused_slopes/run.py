"""The shipped actors under the conditions that tell them a wrong slope, counted two ways (2026-11-29,
twelfth session): as every figure before did (the episodes told a slope outside the actor's trained range run
with the slope observation clipped: `lhd eval --run-refused`) and as the machine's nodes do (those episodes not
run, counted as refused: `lhd eval`, the default since). 120 held-out episodes (seed 2,000,000) a cell.

    .venv/bin/python docs/evidence/refused_slopes/run.py > docs/evidence/refused_slopes/table.md   # about 4 min
"""
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
LHD = str(ROOT / ".venv" / "bin" / "lhd")
ACTORS = [  # (directory, own parameter file?, RLC)
    ("rld", False, False), ("rlc", False, True), ("rld_gains", True, False), ("rlc_gains", True, True),
    ("rld_told_teacher", True, False), ("rld_machine", True, False), ("rlc_twin_sil_bc", True, True)]
CONDITIONS = [("randomised", ["--randomize"]), ("machine case", ["--stress", "machine"]),
              ("rough face", ["--stress", "rough"])]


def run(actor, own, rlc, extra, refuse):
    cmd = [LHD, "eval", "--policy", f"policies/{actor}", "--episodes", "120", "--seed", "2000000", "--json", *extra]
    if own:
        cmd += ["--config", f"policies/{actor}/lhd_params.yaml"]
    if rlc:
        cmd.append("--deploy-filter")
    if not refuse:
        cmd.append("--run-refused")
    out = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=True).stdout
    return json.loads(out)


print("| actor | condition | success, refused run clipped (before) | success, refused counted (now) | refused | "
      "success of the attempts run | AML of the run, kg |")
print("|---|---|---|---|---|---|---|")
for actor, own, rlc in ACTORS:
    for name, extra in CONDITIONS:
        old, new = run(actor, own, rlc, extra, False), run(actor, own, rlc, extra, True)
        print(f"| `{actor}` | {name} | {old['success_rate']:.3f} | {new['success_rate']:.3f} | "
              f"{new['refused']} / {new['episodes']} | {new['success_rate_run']:.3f} | {new['aml']:.1f} |", flush=True)
print(f"\n(`{' '.join(sys.argv)}`; the RLC actors with the deployment filter, as the policy node runs them; each actor "
      "with the parameter file it was trained with, the main job's `rld` / `rlc` with config/lhd_params.yaml)")
