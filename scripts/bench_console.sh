#!/usr/bin/env bash
# Speed of bitewise-console as a browser meets it (docs/benchmarks.md): starts
# the four services and the console (default confirmation: robot) on loopback
# ports as tests/console/browser_test.sh does, runs
# clients/console/web/bench/console_bench.mjs in Debian's chromium against
# them, and stops everything. Builds nothing.
#
#   scripts/bench_console.sh [--loads=10] [--bites=5] [--stops=10]
#   BUILD_DIR=other-build scripts/bench_console.sh
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR="$(cd "${BUILD_DIR:-build}" && pwd)"
export BUILD_DIR
CONSOLE="$BUILD_DIR/clients/console/bitewise-console"
[[ -x $CONSOLE ]] || { echo "no $CONSOLE: build it first" >&2; exit 1; }
DATA_DIR="$(mktemp -d)"

# shellcheck source=scripts/lib/services.sh
source scripts/lib/services.sh
# A port range of our own (random_base_port).
BASE_PORT=$(random_base_port)
CONSOLE_PORT=$((BASE_PORT + 5))
cleanup() { stop_services; rm -rf "$DATA_DIR"; }
trap cleanup EXIT

# A fixed plate, so runs eat the same food.
start_services 1 >/dev/null
# shellcheck disable=SC2046
"$CONSOLE" --listen "127.0.0.1:$CONSOLE_PORT" $(service_flags) \
  --journal "$DATA_DIR/console.journal" >"$DATA_DIR/logs/console.log" 2>&1 &
PIDS+=($!)
for _ in $(seq 1 100); do
  grep -q "bitewise-console: open" "$DATA_DIR/logs/console.log" && break
  sleep 0.1
done
if ! grep -q "bitewise-console: open" "$DATA_DIR/logs/console.log"; then
  echo "bitewise-console did not start:" >&2
  tail -n 20 "$DATA_DIR/logs/console.log" >&2
  exit 1
fi

export BITEWISE_CONSOLE_URL="http://127.0.0.1:$CONSOLE_PORT"
echo "bitewise-console at $BITEWISE_CONSOLE_URL; load: $(cut -d' ' -f1-3 /proc/loadavg)"
status=0
(cd clients/console/web && node bench/console_bench.mjs "$@") || status=$?
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
if ((status != 0)); then
  echo "--- console log" >&2
  tail -n 40 "$DATA_DIR/logs/console.log" >&2
fi
exit "$status"
