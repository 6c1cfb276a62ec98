#!/usr/bin/env bash
# Leave one story out for the familiarity score (docs/haptic.md,
# "Familiarity"): for every trace story, fits the familiarity model on the
# other stories' training windows (bitewise-haptic-train --familiarity_only:
# seed 1, 3,000 items per class and story, the network is not trained), sets
# its threshold on their validation windows (5% flagged), and reports it on
# their test split (familiar) and on 500 fresh items per class of the story
# it left out (seed 1001), with the AUROC between the two, then the mean
# AUROC over the folds. Without LOSO_STORIES, also the configuration of the
# model shipped until 2026-12-06 (world + piecewise).
#
#   scripts/haptic/familiarity_loso.sh OUT_DIR
#   LOSO_STORIES=world,piecewise,mechanics,compliant,puncture,poroelastic \
#     FAMILIARITY_FLAGS=--familiarity_gaussians=class_and_story \
#     JOBS=2 scripts/haptic/familiarity_loso.sh OUT_DIR
#
# About 30 s per fold with four stories, 2 minutes with six, on one core;
# JOBS folds run at a time (default 1). Needs a build of
# bitewise-haptic-train.
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT="${1:?usage: scripts/haptic/familiarity_loso.sh OUT_DIR}"
BUILD_DIR="${BUILD_DIR:-build}"
TRAIN="$BUILD_DIR/services/haptic/bitewise-haptic-train"
IFS=, read -r -a STORIES <<<"${LOSO_STORIES:-world,piecewise,mechanics,compliant}"
read -r -a FLAGS <<<"${FAMILIARITY_FLAGS:-}"
JOBS="${JOBS:-1}"
mkdir -p "$OUT"
fold() {
  local held="$1" others
  others=$(printf '%s\n' "${STORIES[@]}" | grep -vx "$held" | paste -sd,)
  "$TRAIN" --stories="$others" --familiarity_only "${FLAGS[@]}" \
    --out="$OUT/$held.onnx" >"$OUT/$held.log"
}
running=0
for held in "${STORIES[@]}"; do
  fold "$held" &
  running=$((running + 1))
  if ((running >= JOBS)); then
    wait -n
    running=$((running - 1))
  fi
done
wait
sum=0
for held in "${STORIES[@]}"; do
  echo "==> held out $held (fitted on the others)"
  grep -E '^familiarity \(' "$OUT/$held.log"
  grep -E '^  test split' "$OUT/$held.log"
  grep -E "^  held-out story $held " "$OUT/$held.log"
  auroc=$(grep -E "^  held-out story $held " "$OUT/$held.log" |
    sed -E 's/.*AUROC against the test split ([0-9.]+).*/\1/')
  sum=$(awk -v a="$sum" -v b="$auroc" 'BEGIN { printf "%.6f", a + b }')
done
awk -v s="$sum" -v n="${#STORIES[@]}" \
  'BEGIN { printf "mean AUROC over the %d folds: %.3f\n", n, s / n }'
if [[ -z "${LOSO_STORIES:-}" ]]; then
  echo "==> fitted on world,piecewise (the stories of the model shipped until 2026-12-06)"
  "$TRAIN" --stories=world,piecewise --familiarity_only "${FLAGS[@]}" \
    --out="$OUT/shipped.onnx" >"$OUT/shipped.log"
  grep -E '^  (test split|held-out story)' "$OUT/shipped.log"
fi
