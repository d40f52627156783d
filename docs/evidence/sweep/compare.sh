#!/usr/bin/env bash
# The 2 variants x 5 seeds study through `lhd train --seeds` (one variant after the other, as a
# user types it) and through `lhd sweep` (one Ray study), on this machine, at STEPS steps a run.
# Usage: bash docs/evidence/sweep/compare.sh [STEPS] [OUT]   (from the repository root)
set -euo pipefail
STEPS=${1:-10000}
OUT=${2:-/tmp/lhd_sweep_compare}
LHD=${LHD:-.venv/bin/lhd}
rm -rf "$OUT" && mkdir -p "$OUT"
t0=$(date +%s.%N)
"$LHD" train --variant rld --seeds 0-4 --steps "$STEPS" --out "$OUT/train/rld" > "$OUT/train_rld.log" 2>&1
"$LHD" train --variant rlc --seeds 0-4 --steps "$STEPS" --out "$OUT/train/rlc" > "$OUT/train_rlc.log" 2>&1
t1=$(date +%s.%N)
cat > "$OUT/study.yaml" <<YAML
out: sweep
variants: [rld, rlc]
seeds: 0-4
steps: $STEPS
YAML
"$LHD" sweep "$OUT/study.yaml" > "$OUT/sweep.log" 2>&1
t2=$(date +%s.%N)
python3 - "$t0" "$t1" "$t2" "$STEPS" "$(nproc)" <<'PY'
import sys
t0, t1, t2 = map(float, sys.argv[1:4])
a, b = t1 - t0, t2 - t1
print(f"steps per run {sys.argv[4]}, {sys.argv[5]} cores: lhd train --seeds (rld then rlc) {a:.0f} s, "
      f"lhd sweep {b:.0f} s, sweep / train = {b / a:.3f}")
PY
