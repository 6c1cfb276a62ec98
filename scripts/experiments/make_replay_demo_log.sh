#!/usr/bin/env bash
# Collects a real BanditService event log to demonstrate bitewise-replay:
# starts bitewise-bandit on a private port with a fresh SQLite file whose new
# users explore uniformly at random (so the doubly robust estimate with
# weight K is unbiased), then runs simulated meals of the bandit demo client
# (seeds 1..N) for one user. Usage:
#   make_replay_demo_log.sh <build dir> <db path> [meals=10] [port=50071]
set -euo pipefail
build="$1"
db="$2"
meals="${3:-10}"
port="${4:-50071}"
rm -f "$db" "$db-wal" "$db-shm"
mkdir -p "$(dirname "$db")"
"$build/services/bandit/bitewise-bandit" --db "$db" --create --default_strategy uniform \
  --listen "127.0.0.1:$port" >/dev/null 2>&1 &
server=$!
trap 'kill "$server" 2>/dev/null; wait "$server" 2>/dev/null || true' EXIT
for _ in $(seq 50); do
  "$build/clients/health/bitewise-health" --address "127.0.0.1:$port" \
    >/dev/null 2>&1 && break
  sleep 0.1
done
for seed in $(seq "$meals"); do
  "$build/clients/bandit_demo/bitewise-bandit-demo" --bandit "127.0.0.1:$port" \
    --user uniform-logger --meal "meal-$seed" --seed "$seed" --bites 40 \
    >/dev/null
done
echo "logged $meals meals for user uniform-logger in $db"
