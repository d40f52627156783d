#!/usr/bin/env bash
# A pile lower or higher than the paper's 0.68 m (a pile dumped by hand), from the repository root (about 4 min):
#   bash docs/evidence/pile_height/run.sh > docs/evidence/pile_height/pile_height.txt
# Each actor's own parameter file with paper.episode.h_pile set to 0.55 / 0.68 / 0.85 m, `lhd eval --stress machine`
# (placed by hand, from rest, on a rough pile), 120 held-out episodes, RLC with the deployment filter, the zones the
# pile's own and the end-zone node's. The file sets the height for the simulated pile and for the zones alike, so
# the end-zone node here knows the pile's height; on the machine it assumes the config's 0.68 m, which moves only
# the restricted zone (h / tan(alpha) - d_cutoff): farther than the pile's for a lower pile, nearer for a higher.
# The observation's normalisers do not move (they derive from the shallowest pile, whose crest lies beyond x_max).
set -euo pipefail
T=$(mktemp -d)
for a in rld_machine rlc_gains; do
  filt=(); case $a in rlc*) filt=(--deploy-filter);; esac
  for h in 0.55 0.68 0.85; do
    sed "s/^    h_pile: 0.68 /    h_pile: $h /" policies/$a/lhd_params.yaml > $T/${a}_$h.yaml
    grep -q "h_pile: $h " $T/${a}_$h.yaml
    for z in pile end-zone-node; do
      echo "== $a, pile $h m high, zones: $z"
      .venv/bin/lhd eval --policy policies/$a --config $T/${a}_$h.yaml "${filt[@]}" --episodes 120 --seed 2000000 \
          --stress machine --zones $z | grep -E "^ +(all|15 deg|20 deg|25 deg|30 deg) |failures"
    done
  done
done
rm -rf "$T"
