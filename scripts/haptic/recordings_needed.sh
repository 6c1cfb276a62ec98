#!/usr/bin/env bash
# How much recorded data moves HapticNet on a new story (docs/haptic.md,
# "The lab's own data"): the story stands for the lab's fork. For each N,
# N items per class of STORY (seed 77, so not the evaluation items) are
# written in the recording format, the trainer learns from them together
# with the stories in STORIES (default world,piecewise, seed 1: the
# trainer's default until 2026-12-06, which most documented runs used; the
# six-story runs on lattice set STORIES to the six; STORY must not be among
# them), and its reference pass scores 500 fresh items
# per class of STORY (seed 1001).
#
#   scripts/haptic/recordings_needed.sh OUT STORY [trainer flags...]
#   e.g. scripts/haptic/recordings_needed.sh /tmp/rec compliant --window_s=0.1
#
# Prints one line per N: accuracy and per-class recall on STORY. BUILD_DIR
# (default build) names the build. Each N trains once (2-5 minutes).
set -euo pipefail
OUT=${1:?usage: recordings_needed.sh OUT STORY [trainer flags...]}
STORY=${2:?usage: recordings_needed.sh OUT STORY [trainer flags...]}
shift 2
TRAIN="${BUILD_DIR:-build}/services/haptic/bitewise-haptic-train"
mkdir -p "$OUT"
for n in ${COUNTS:-10 25 50 100 250}; do
  if [ ! -f "$OUT/rec$n.csv" ]; then
    "$TRAIN" --stories="$STORY" --traces_per_class="$n" --seed=77 \
      --write_traces="$OUT/rec$n.csv" --write_traces_only >/dev/null
  fi
  if [ ! -f "$OUT/model$n.onnx" ]; then
    "$TRAIN" --traces="$OUT/rec$n.csv" --stories="${STORIES:-world,piecewise}" \
      "$@" --out="$OUT/model$n.onnx" \
      >"$OUT/train$n.log"
  fi
  held=$(grep -A6 "held-out story $STORY (never" "$OUT/train$n.log")
  echo "$n per class: $(echo "$held" | head -1 | grep -o 'accuracy [0-9.]*%')," \
    "recall hard/medium/soft/hard-skin" \
    "$(echo "$held" | grep -E '^(hard|medium|soft|hard_skin) ' | awk '{print $NF}' | paste -sd/)," \
    "$(echo "$held" | head -1 | grep -o 'calibration error [0-9.]*')"
done
