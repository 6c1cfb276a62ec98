#!/usr/bin/env bash
# The main job: builds bitewise (installing missing packages first), starts
# the four services on loopback with their embedded defaults (simulated
# robot, default featurizer, shipped HapticNet, SQLite in data/), waits until
# every one reports SERVING, runs a meal of the eight unseen foods for a user
# through the orchestrator, prints the summary and stops the services
# cleanly. Run it again and the same user continues from what it learned.
#
#   scripts/meal.sh [--user NAME] [--meal ID] [orchestrator flags, e.g.
#                   --posthoc=none --bites=5 --confirm=operator]
set -euo pipefail
cd "$(dirname "$0")/.."

USER_ID="demo-user"
MEAL=""
EXTRA=()
while (($#)); do
  case "$1" in
    --user) USER_ID="$2"; shift 2 ;;
    --user=*) USER_ID="${1#--user=}"; shift ;;
    --meal) MEAL="$2"; shift 2 ;;
    --meal=*) MEAL="${1#--meal=}"; shift ;;
    *) EXTRA+=("$1"); shift ;;
  esac
done

scripts/setup.sh

DATA_DIR="${BITEWISE_DATA_DIR:-$PWD/data}"
BASE_PORT="${BITEWISE_BASE_PORT:-50051}"
mkdir -p "$DATA_DIR/logs"
# Each meal gets a new plate: the simulated world is seeded by a meal counter.
COUNTER="$DATA_DIR/meals.count"
MEAL_NUMBER=$(( $(cat "$COUNTER" 2>/dev/null || echo 0) + 1 ))
echo "$MEAL_NUMBER" >"$COUNTER"
if [ -z "$MEAL" ]; then MEAL="meal-$MEAL_NUMBER"; fi

PIDS=()
stop_services() {
  for pid in "${PIDS[@]}"; do kill -TERM "$pid" 2>/dev/null || true; done
  for pid in "${PIDS[@]}"; do wait "$pid" 2>/dev/null || true; done
  PIDS=()
}
trap stop_services EXIT

# start NAME SERVICE PORT BINARY [ARGS...]
start() {
  local name="$1" service="$2" port="$3" binary="$4"
  shift 4
  "$binary" --listen "127.0.0.1:$port" "$@" >>"$DATA_DIR/logs/$name.log" 2>&1 &
  PIDS+=($!)
  if ! build/clients/health/bitewise-health --address "127.0.0.1:$port" \
    --service "bitewise.v1.$service" --timeout_s 60 >/dev/null; then
    echo "$service did not become healthy; last lines of $DATA_DIR/logs/$name.log:" >&2
    tail -n 20 "$DATA_DIR/logs/$name.log" >&2
    exit 1
  fi
  printf '    %-18s 127.0.0.1:%s  SERVING\n' "$service" "$port"
}

printf '\n==> Starting the services (logs in %s/logs)\n' "$DATA_DIR"
start bandit BanditService "$BASE_PORT" build/services/bandit/bitewise-bandit \
  --db "$DATA_DIR/bandit.db" --create
start perception PerceptionService "$((BASE_PORT + 1))" \
  build/services/perception/bitewise-perception
start haptic HapticService "$((BASE_PORT + 2))" build/services/haptic/bitewise-haptic
start robot RobotService "$((BASE_PORT + 3))" build/services/robot/bitewise-robot \
  --backend sim --seed "$MEAL_NUMBER"

printf '\n==> Meal %s for user %s (simulated plate %d)\n' "$MEAL" "$USER_ID" "$MEAL_NUMBER"
status=0
build/clients/orchestrator/bitewise-orchestrator --user "$USER_ID" --meal "$MEAL" \
  --bandit "127.0.0.1:$BASE_PORT" --perception "127.0.0.1:$((BASE_PORT + 1))" \
  --haptic "127.0.0.1:$((BASE_PORT + 2))" --robot "127.0.0.1:$((BASE_PORT + 3))" \
  --journal "$DATA_DIR/orchestrator.journal" "${EXTRA[@]}" || status=$?

printf '\n==> Stopping the services\n'
stop_services
trap - EXIT
if [ "$status" -eq 0 ]; then
  echo "done; run scripts/meal.sh --user $USER_ID again to continue learning"
fi
exit "$status"
