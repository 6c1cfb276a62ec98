#!/usr/bin/env bash
# The main job: builds bitewise (installing missing packages first), starts
# the BanditService on loopback with its embedded defaults (SQLite in
# data/), waits until it is SERVING, runs a simulated meal for a user, and
# stops the service cleanly. Run it again and the same user continues from
# what the model has learned.
#
#   scripts/meal.sh [--user NAME] [--meal ID] [--bites N] [--learner posthoc|context_only]
set -euo pipefail
cd "$(dirname "$0")/.."

USER_ID="demo-user"
MEAL=""
DEMO_ARGS=()
while (($#)); do
  case "$1" in
    --user) USER_ID="$2"; shift 2 ;;
    --meal) MEAL="$2"; shift 2 ;;
    *) DEMO_ARGS+=("$1"); shift ;;
  esac
done

scripts/setup.sh

DATA_DIR="${BITEWISE_DATA_DIR:-$PWD/data}"
PORT="${BITEWISE_BANDIT_PORT:-50051}"
mkdir -p "$DATA_DIR"
LOG="$DATA_DIR/bandit.log"
if [ -z "$MEAL" ]; then MEAL="meal-$(date +%Y%m%d-%H%M%S)"; fi

printf '\n==> Starting BanditService on 127.0.0.1:%s (db %s, log %s)\n' \
  "$PORT" "$DATA_DIR/bandit.db" "$LOG"
build/services/bandit/bitewise-bandit --listen "127.0.0.1:$PORT" \
  --db "$DATA_DIR/bandit.db" >>"$LOG" 2>&1 &
SERVER_PID=$!
stop_server() {
  if kill -0 "$SERVER_PID" 2>/dev/null; then
    kill -TERM "$SERVER_PID"
    wait "$SERVER_PID" || true
  fi
}
trap stop_server EXIT

if ! build/clients/health/bitewise-health --address "127.0.0.1:$PORT" \
  --service bitewise.v1.BanditService --timeout_s 20; then
  echo "BanditService did not become healthy; last log lines:" >&2
  tail -n 20 "$LOG" >&2
  exit 1
fi

printf '\n==> Simulated meal %s for user %s\n' "$MEAL" "$USER_ID"
build/clients/bandit_demo/bitewise-bandit-demo --bandit "127.0.0.1:$PORT" \
  --user "$USER_ID" --meal "$MEAL" "${DEMO_ARGS[@]}"

printf '\n==> Stopping BanditService\n'
stop_server
trap - EXIT
echo "done; run again to continue learning for $USER_ID"
