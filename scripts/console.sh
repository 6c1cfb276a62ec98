#!/usr/bin/env bash
# bitewise-console on the embedded defaults: builds bitewise (installing
# missing packages first), starts the four services on loopback (simulated
# robot and plate, default featurizer, shipped HapticNet, SQLite in data/),
# then the console, and prints the URL to open. Ctrl-C stops everything.
#
#   scripts/console.sh [--port N] [console flags, e.g. --confirm=operator]
set -euo pipefail
cd "$(dirname "$0")/.."

PORT="${BITEWISE_CONSOLE_PORT:-8080}"
EXTRA=()
while (($#)); do
  case "$1" in
    --port) PORT="$2"; shift 2 ;;
    --port=*) PORT="${1#--port=}"; shift ;;
    *) EXTRA+=("$1"); shift ;;
  esac
done

scripts/setup.sh

# shellcheck source=scripts/lib/services.sh
source scripts/lib/services.sh
PLATE=$(next_plate)
trap stop_services EXIT
start_services "$PLATE"

printf '\n==> Starting bitewise-console (log in %s/logs/console.log)\n' "$DATA_DIR"
# shellcheck disable=SC2046
build/clients/console/bitewise-console --listen "127.0.0.1:$PORT" $(service_flags) \
  --journal "$DATA_DIR/console.journal" "${EXTRA[@]}" >>"$DATA_DIR/logs/console.log" 2>&1 &
PIDS+=($!)
for _ in $(seq 1 100); do
  if grep -q "bitewise-console: open" "$DATA_DIR/logs/console.log" 2>/dev/null; then break; fi
  if ! kill -0 "${PIDS[-1]}" 2>/dev/null; then
    echo "bitewise-console exited; last lines of its log:" >&2
    tail -n 20 "$DATA_DIR/logs/console.log" >&2
    exit 1
  fi
  sleep 0.1
done
printf '\n    Open http://127.0.0.1:%s/ in a browser (table view; #/research for the researcher view).\n' "$PORT"
printf '    Press Ctrl-C to stop the console and the services.\n\n'
wait "${PIDS[-1]}" || true
