#!/usr/bin/env bash
# The population-prior runs of docs/experiments.md, on seed 1: 4 facilities
# x 20 pooled people x 3 meals, 50 new people per facility, when the pooled
# people ate the new person's foods (unseen) and when they ate none of them
# (seen). The prior's weight n0 = 4 was chosen on seed 101 (one facility,
# 20 new people: the best worst case over the two scenarios among 4, 16 and
# 64); 16 and 64 are reported beside it for information.
# Usage: scripts/experiments/sim_prior.sh [build dir] [output dir]
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
build="${1:-$root/build}"
out="${2:-$root/experiments/results}"
mkdir -p "$out"
cmake --build "$build" -j2 --target bitewise-sim-prior
for foods in unseen seen; do
  nice -n 10 "$build/experiments/bitewise-sim-prior" --facilities=4 \
    --new_users=50 --prior_rounds=4,16,64 --pool_foods="$foods" --seed=1 \
    2>/dev/null | tee "$out/sim_prior_$foods.txt" &
done
wait
