#!/usr/bin/env bash
# The simulated-meals runs of docs/experiments.md: the shipped defaults
# (exactly what scripts/meal.sh uses: rho_c = 1 on the default featurizer's
# seen-food E||c||^2, alpha 0.01, lambda_p 1, a new piece at every attempt),
# 400 paired trials on seed 1 (context-only and post hoc LinUCB with three
# haptic encodings, and Thompson sampling for both learners), and the
# sensitivity cells on the same seed: rho_c 0.3 and 3, blocked order,
# HapticNet degraded to 95% and 80%, the (seeded, untrained) SPANet
# featurizer, a look-alike pair on the plate, and traces from trace stories
# that the two-story HapticNet shipped until 2026-12-06 never saw (mechanics,
# compliant; docs/haptic.md), and the actions' force limits cutting the
# traces.
# The learners' settings were not chosen on these seeds (Thompson's v = 0.03
# and phi_radius on seed 1001); two product defaults were chosen on seed 1's
# cells (the log-probability encoding, and on 2026-12-03 poLinUCB, since
# undone by a rule fixed in advance): docs/experiments.md says which. Nine
# committed files were made at Thompson's old v = 0.5 (listed there); this
# script runs v = 0.03 and does not reproduce their Thompson rows.
# The files in experiments/results were made with that two-story model; the
# embedded model is now the six-story one. To reproduce them, train the old
# one (bitewise-haptic-train --stories=world,piecewise
# --familiarity_gaussians=class --out=/abs/two.onnx)
# and set SIM_MEALS_FLAGS=--haptic_model=/abs/two.onnx (flags added to
# every run, split on spaces).
# Usage: [SIM_MEALS_FLAGS=...] scripts/experiments/sim_meals_all.sh [build dir] [output dir]
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
build="${1:-$root/build}"
out="${2:-$root/experiments/results}"
mkdir -p "$out"
cmake --build "$build" -j2 --target bitewise-sim-meals
meals() {
  local name="$1"
  shift
  echo "+ bitewise-sim-meals ${SIM_MEALS_FLAGS:-} $* -> $out/$name.{csv,txt}" >&2
  # shellcheck disable=SC2086  # SIM_MEALS_FLAGS: flags, split on spaces
  nice -n 10 "$build/experiments/bitewise-sim-meals" --trials=400 --seed=1 \
    ${SIM_MEALS_FLAGS:-} --out="$out/$name.csv" "$@" 2>/dev/null |
    tee "$out/$name.txt"
}
# Two lanes, one per core.
(
  meals sim_meals
  meals sim_meals_rho3 --rho_c=3
  meals sim_meals_haptic95 --haptic_accuracy=0.95
  meals sim_meals_spanet --spanet_model="$build/models/spanet_seed1.onnx"
  meals sim_meals_story_mechanics --trace_story=mechanics
) &
lane=$!
meals sim_meals_rho0.3 --rho_c=0.3
meals sim_meals_blocked --order=blocked
meals sim_meals_haptic80 --haptic_accuracy=0.8
# A look-alike pair on the plate: unripe banana (medium) in place of kiwi,
# looking like the ripe banana (soft).
meals sim_meals_lookalike \
  --foods=carrot,celery,strawberry,cantaloupe,banana,banana_unripe,cherry_tomato,grape
meals sim_meals_story_compliant --trace_story=compliant
# The actions' force limits cutting the traces (docs/experiments.md, "A trace
# the robot cut short"; the rule was chosen on seed 2).
meals sim_meals_force_limit_seed1 --force_limit
wait "$lane"
if command -v gnuplot >/dev/null; then
  gnuplot -e "dir='$out'; out='$out'; name='sim_meals'" \
    "$root/scripts/experiments/plot_sim_meals.gp"
fi
