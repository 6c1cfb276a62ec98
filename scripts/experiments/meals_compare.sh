#!/usr/bin/env bash
# Whole meals through the real services (scripts/meal.sh: four services +
# orchestrator), post hoc haptic context against vision only, paired: user
# pair u has a post hoc user (and, with --arms posthoc,polinucb, a poLinUCB
# user) and a vision-only user who eat the same
# simulated plates (meal m of pair u uses plate seed 1000*(u-1)+m for both),
# each continuing from its own model across meals. Prints failures per meal
# with 95% intervals over the pairs and the paired difference.
#
#   scripts/experiments/meals_compare.sh [--users N] [--meals M] [--jobs J]
#                                        [--arms posthoc,polinucb]
#                                        [orchestrator flags...]
# e.g. scripts/experiments/meals_compare.sh --users 10 --meals 5
#      scripts/experiments/meals_compare.sh --users 10 --meals 5 --lambda_c=10
# A meal takes about a minute of wall time and 7 s of CPU (the simulated arm
# moves in real time), so J pairs run side by side, each with its own data
# directory and ports (BITEWISE_BASE_PORT 50200 + 10 u). Data:
# $BITEWISE_DATA_DIR (default data/meals-compare), wiped at the start; the
# per-meal lines land in $BITEWISE_DATA_DIR/meals.tsv.
set -euo pipefail
cd "$(dirname "$0")/../.."
USERS=10
MEALS=5
JOBS=4
ARMS=posthoc
EXTRA=()
while (($#)); do
  case "$1" in
    --users) USERS="$2"; shift 2 ;;
    --meals) MEALS="$2"; shift 2 ;;
    --jobs) JOBS="$2"; shift 2 ;;
    --arms) ARMS="$2"; shift 2 ;;
    *) EXTRA+=("$1"); shift ;;
  esac
done
ROOT="${BITEWISE_DATA_DIR:-$PWD/data/meals-compare}"
rm -rf "$ROOT"
mkdir -p "$ROOT"
scripts/setup.sh --meal >/dev/null  # the meal.sh programs only

# One pair's meals, in order: both users eat meal m before meal m+1.
run_pair() {
  local u="$1"
  local dir="$ROOT/pair-$u"
  mkdir -p "$dir/out"
  for m in $(seq 1 "$MEALS"); do
    for learner in ${ARMS//,/ } vision; do
      local flags=("${EXTRA[@]}")
      [ "$learner" = vision ] && flags+=(--posthoc=none)
      [ "$learner" = posthoc ] && flags+=(--learner=posthoc)
      [ "$learner" = polinucb ] && flags+=(--learner=polinucb)
      echo $((1000 * (u - 1) + m - 1)) >"$dir/meals.count"
      local out="$dir/out/$learner-$m.txt"
      BITEWISE_DATA_DIR="$dir" BITEWISE_BASE_PORT=$((50200 + 10 * u)) \
        scripts/meal.sh --user "$learner-$u" --meal "meal-$m" \
        "${flags[@]}" >"$out" 2>&1 || true
      local line
      line=$(grep -oE 'meal meal-[0-9]+: [0-9]+ attempts, [0-9]+ failures?' \
        "$out" || true)
      if [ -z "$line" ]; then
        echo "pair $u meal $m $learner FAILED, see $out" >&2
        continue
      fi
      read -r attempts failures < <(echo "$line" |
        sed -E 's/.*: ([0-9]+) attempts, ([0-9]+) failures?/\1 \2/')
      printf '%d\t%d\t%s\t%d\t%d\n' "$u" "$m" "$learner" "$attempts" \
        "$failures" >>"$ROOT/meals.tsv"
      printf 'pair %2d meal %d %-8s %3d attempts %3d failures\n' "$u" "$m" \
        "$learner" "$attempts" "$failures"
    done
  done
}

for u in $(seq 1 "$USERS"); do
  # At most JOBS pairs at once.
  while (($(jobs -rp | wc -l) >= JOBS)); do wait -n || true; done
  run_pair "$u" &
done
wait

python3 scripts/experiments/meals_compare_summary.py "$ROOT/meals.tsv" \
  "$USERS" "$MEALS" "$ARMS" | tee "$ROOT/summary.txt"
