#!/usr/bin/env bash
# The Tampier-style heuristic with its bury-lift-tilt timing changed, one threshold set at a time
# (config/tampier.yaml copied to a temporary file), 40 homogeneous attempts on 15-30 deg piles each:
# does its timing explain its 10 s attempts and failures in the restricted zone? (docs/baselines.md
# "The heuristic's timing is not the cause"). Run from the repository root: bash docs/evidence/dry_gravel/tampier_timing.sh
set -euo pipefail
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
for v in "0.5 0.5 20" "1.0 0.5 20" "1.0 0.3 20" "0.5 0.5 10" "1.5 0.5 20"; do
  set -- $v
  sed -e "s/^  lift_time: 0.5 /  lift_time: $1 /" -e "s/^  tilt_time: 0.5 /  tilt_time: $2 /" \
      -e "s/^  boom_full_deg: 20.0 /  boom_full_deg: $3 /" config/tampier.yaml > "$tmp/t.yaml"
  echo "== lift_time $1 s, tilt_time $2 s, boom_full_deg $3"
  .venv/bin/lhd eval --controller tampier --episodes 40 --material homogeneous --tampier-config "$tmp/t.yaml" | sed -n 2,8p
done
