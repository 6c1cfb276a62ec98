#!/usr/bin/env bash
# Runs N whole meals (scripts/meal.sh: four services + orchestrator) for two
# users, one learning with post hoc haptic context and one from vision only,
# on the same simulated plates (meal m uses plate seed m for both), and
# prints failures by meal. Each user continues from its model across meals.
#
#   scripts/experiments/meals_compare.sh [--meals N] [orchestrator flags...]
# e.g. scripts/experiments/meals_compare.sh --meals 5 --lambda_c=10
# Takes about 70 s per meal per user. Data: $BITEWISE_DATA_DIR (default
# data/meals-compare), wiped at the start.
set -euo pipefail
cd "$(dirname "$0")/../.."
MEALS=5
EXTRA=()
while (($#)); do
  case "$1" in
    --meals) MEALS="$2"; shift 2 ;;
    *) EXTRA+=("$1"); shift ;;
  esac
done
export BITEWISE_DATA_DIR="${BITEWISE_DATA_DIR:-$PWD/data/meals-compare}"
rm -rf "$BITEWISE_DATA_DIR"
mkdir -p "$BITEWISE_DATA_DIR/out"
for m in $(seq 1 "$MEALS"); do
  for learner in posthoc vision; do
    flags=("${EXTRA[@]}")
    [ "$learner" = vision ] && flags+=(--posthoc=none)
    echo $((m - 1)) >"$BITEWISE_DATA_DIR/meals.count"  # plate seed m for both
    scripts/meal.sh --user "$learner-user" --meal "meal-$m" "${flags[@]}" \
      >"$BITEWISE_DATA_DIR/out/$learner-$m.txt" 2>&1 || true
    printf 'meal %d %-8s %s\n' "$m" "$learner" \
      "$(grep -o 'meal meal-[0-9]*: [0-9]* attempts, [0-9]* failures' \
        "$BITEWISE_DATA_DIR/out/$learner-$m.txt" || echo 'FAILED, see the output file')"
  done
done
