#!/usr/bin/env bash
# Leave one story out (docs/haptic.md, "Held-out stories"): for every trace
# story, trains HapticNet on the other stories, evaluates it the way the
# service runs it on the story it never saw (tuning items, seed 7, and report
# items, seed 20261123), then chooses each fold's softmax temperature from
# the OTHER folds' tuning items and prints the tables of docs/haptic.md.
#
#   scripts/haptic/leave_one_story_out.sh OUT_DIR [trainer flags...]
#   e.g. scripts/haptic/leave_one_story_out.sh /tmp/loso --augment
#
# About 5 minutes per story on one core. Needs a build (scripts/setup.sh).
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT="${1:?usage: scripts/haptic/leave_one_story_out.sh OUT_DIR [trainer flags...]}"
shift
BUILD_DIR="${BUILD_DIR:-build}"
STORIES=(world piecewise mechanics compliant)
mkdir -p "$OUT"
for held in "${STORIES[@]}"; do
  others=$(printf '%s\n' "${STORIES[@]}" | grep -vx "$held" | paste -sd,)
  if [ ! -f "$OUT/$held.onnx" ]; then
    echo "==> training on $others (holding out $held)"
    "$BUILD_DIR"/services/haptic/bitewise-haptic-train --stories="$others" "$@" \
      --out="$OUT/$held.onnx" >"$OUT/$held.train.log"
  fi
  for part in tune:7 report:20261123; do
    "$BUILD_DIR"/services/haptic/bitewise-haptic-eval --model="$OUT/$held.onnx" \
      --stories="$held" --seed="${part#*:}" \
      --probabilities_csv="$OUT/$held.${part%%:*}.csv" >"$OUT/$held.${part%%:*}.log"
  done
done
# Debian's python3 (python3-numpy, which scripts/setup.sh installs) first.
PYTHON=python3
if [ -x /usr/bin/python3 ]; then PYTHON=/usr/bin/python3; fi
"$PYTHON" scripts/haptic/story_calibration.py "$OUT" "${STORIES[@]}"
