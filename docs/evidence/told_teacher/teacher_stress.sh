#!/usr/bin/env bash
# The two end-zone baselines (the demonstrations' teacher and the Tampier-style heuristic) under every
# stress case of `lhd eval --stress`, in process, 15-30 deg piles of both materials, 10 attempts a cell
# (80 per controller and case), the same piles for both. Run from the repository root:
#   bash docs/evidence/told_teacher/teacher_stress.sh > docs/evidence/told_teacher/teacher_stress.txt
set -euo pipefail
OUT=${TMPDIR:-/tmp}/teacher_stress
mkdir -p "$OUT"
for st in none placement sensors delay light dense rocky rough slow_drive slow_hydraulics cohesive; do
  a=(); [ "$st" != none ] && a=(--stress "$st")
  .venv/bin/lhd experiment paper --controllers teacher,tampier --episodes 10 --jobs 2 --errors=0 "${a[@]}" \
      --out "$OUT/$st" > "$OUT/$st.log" 2>&1
  .venv/bin/python - "$OUT/$st/attempts.csv" "$st" <<'PY'
import csv, sys
rows = [x for x in csv.DictReader(open(sys.argv[1])) if x["table"] == "controllers"]
cells = []
for c in ("teacher", "tampier"):
    r = [x for x in rows if x["controller"] == c]
    ok = [x for x in r if x["success"] == "True"]
    m = sum(float(x["loaded_kg"]) for x in ok) / len(ok) if ok else float("nan")
    why = {}
    for x in r:
        if x["success"] != "True":
            k = "restricted zone" if x["failed"] == "True" else ("timeout" if x["timeout"] == "True" else "end zone below SL 1")
            why[k] = why.get(k, 0) + 1
    cells.append(f"{len(ok)}/{len(r)}, {m:.1f} kg, failures {why or '-'}")
print(f"| {sys.argv[2]} | " + " | ".join(cells) + " |")
PY
done
