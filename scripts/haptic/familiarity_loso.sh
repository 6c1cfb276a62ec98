#!/usr/bin/env bash
# Leave one story out for the familiarity score (docs/haptic.md,
# "Familiarity"): for every trace story, fits the familiarity model on the
# other three stories' training windows (bitewise-haptic-train
# --familiarity_only: seed 1, 3,000 items per class and story, the network is
# not trained), sets its threshold on their validation windows (5% flagged),
# and reports it on their test split (familiar) and on 500 fresh items per
# class of the story it never saw (seed 1001), with the AUROC between the
# two. Also the shipped configuration (world + piecewise).
#
#   scripts/haptic/familiarity_loso.sh OUT_DIR
#
# About 30 s per fold on one core. Needs a build of bitewise-haptic-train.
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT="${1:?usage: scripts/haptic/familiarity_loso.sh OUT_DIR}"
BUILD_DIR="${BUILD_DIR:-build}"
TRAIN="$BUILD_DIR/services/haptic/bitewise-haptic-train"
STORIES=(world piecewise mechanics compliant)
mkdir -p "$OUT"
for held in "${STORIES[@]}"; do
  others=$(printf '%s\n' "${STORIES[@]}" | grep -vx "$held" | paste -sd,)
  echo "==> fitted on $others, holding out $held"
  "$TRAIN" --stories="$others" --familiarity_only --out="$OUT/$held.onnx" \
    >"$OUT/$held.log"
  grep -E '^  (test split|held-out story)' "$OUT/$held.log"
done
echo "==> fitted on world,piecewise (the stories of the model shipped until 2026-12-06)"
"$TRAIN" --stories=world,piecewise --familiarity_only --out="$OUT/shipped.onnx" \
  >"$OUT/shipped.log"
grep -E '^  (test split|held-out story)' "$OUT/shipped.log"
