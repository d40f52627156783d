#!/usr/bin/env bash
# The two end-zone baselines (the demonstrations' teacher and the Tampier-style heuristic) under every
# stress case of `lhd eval --stress`, in process, 15-30 deg piles of both materials, 10 attempts a cell
# (80 per controller and case), the same piles for both. The in-process teacher reads the simulator's
# state (true drift flags, true v_x): the `sensors` case's noise reaches the RL actors only. Run from the
# repository root (writes teacher_stress.md and teacher_stress/<case>.csv, every attempt):
#   bash docs/evidence/told_teacher/teacher_stress.sh
set -euo pipefail
OUT=${TMPDIR:-/tmp}/teacher_stress
E=docs/evidence/told_teacher
mkdir -p "$OUT" $E/teacher_stress
{
echo "| stress case | teacher: successes, mass over successes, failures | Tampier-style heuristic |"
echo "| --- | --- | --- |"
for st in none placement sensors delay light dense rocky rough slow_drive slow_hydraulics cohesive; do
  a=(); [ "$st" != none ] && a=(--stress "$st")
  .venv/bin/lhd experiment paper --controllers teacher,tampier --episodes 10 --jobs 2 --errors=0 "${a[@]}" \
      --out "$OUT/$st" > "$OUT/$st.log" 2>&1
  cp "$OUT/$st/attempts.csv" $E/teacher_stress/$st.csv
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
            if x["failed"] == "True" or x["timeout"] == "True":
                k = "restricted zone" if x["failed"] == "True" else "timeout"
            else:
                k = "end zone, under 20 kg" if float(x["loaded_kg"]) < 20.0 else "end zone, curl under 40 deg"
            why[k] = why.get(k, 0) + 1
    cells.append(f"{len(ok)}/{len(r)}, {m:.1f} kg, failures {why or '-'}")
print(f"| {sys.argv[2]} | " + " | ".join(cells) + " |")
PY
done
} > $E/teacher_stress.md
