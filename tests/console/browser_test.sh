#!/usr/bin/env bash
# The web app in a real browser: starts the four service binaries and
# bitewise-console (operator confirmation, so the question path runs) on
# free loopback ports, then runs the puppeteer-core tests of
# clients/console/web/test in Debian's chromium against them. Screenshots go
# to $BITEWISE_SCREENSHOT_DIR (default: BUILD/console-screenshots).
#
#   tests/console/browser_test.sh BUILD_DIR
set -euo pipefail
cd "$(dirname "$0")/../.."
BUILD_DIR="$(cd "${1:?usage: browser_test.sh BUILD_DIR}" && pwd)"
export BUILD_DIR
DATA_DIR="$(mktemp -d)"
export BITEWISE_SCREENSHOT_DIR="${BITEWISE_SCREENSHOT_DIR:-$BUILD_DIR/console-screenshots}"
mkdir -p "$BITEWISE_SCREENSHOT_DIR"

# shellcheck source=scripts/lib/services.sh
source scripts/lib/services.sh
# A port range of our own (random_base_port).
BASE_PORT=$(random_base_port)
CONSOLE_PORT=$((BASE_PORT + 5))
cleanup() { stop_services; rm -rf "$DATA_DIR"; }
trap cleanup EXIT

export BITEWISE_CONSOLE_URL="http://127.0.0.1:$CONSOLE_PORT"
export BITEWISE_CONSOLE_OPERATOR=1
status=0
# Each test file eats from the plate: each gets a fresh plate, a fresh
# console and a fresh store.
for test_file in clients/console/web/test/*.test.mjs; do
  rm -rf "${DATA_DIR:?}"/*
  start_services 5 >/dev/null
  # shellcheck disable=SC2046
  "$BUILD_DIR/clients/console/bitewise-console" --listen "127.0.0.1:$CONSOLE_PORT" \
    $(service_flags) --confirm=operator --journal "$DATA_DIR/console.journal" \
    >"$DATA_DIR/logs/console.log" 2>&1 &
  PIDS+=($!)
  for _ in $(seq 1 100); do
    grep -q "bitewise-console: open" "$DATA_DIR/logs/console.log" && break
    sleep 0.1
  done
  if ! grep -q "bitewise-console: open" "$DATA_DIR/logs/console.log"; then
    status=1
    echo "--- bitewise-console did not open on 127.0.0.1:$CONSOLE_PORT ($test_file)" >&2
    tail -n 20 "$DATA_DIR/logs/console.log" >&2
    stop_services
    continue
  fi
  if ! (cd clients/console/web && node --test "test/$(basename "$test_file")"); then
    status=1
    echo "--- console log ($test_file)" >&2
    tail -n 40 "$DATA_DIR/logs/console.log" >&2
  fi
  stop_services
done
exit "$status"
