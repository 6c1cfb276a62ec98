# Sourced by scripts/meal.sh and scripts/console.sh: starts the four services
# on loopback with their embedded defaults and stops them on exit.
#   DATA_DIR, BASE_PORT: where data and logs go (default data/, or
#   $BITEWISE_DATA_DIR), and the first port (50051, or $BITEWISE_BASE_PORT);
#   BUILD_DIR: the build (default build/).
#   start_services SEED: starts them (the simulated plate seeded by SEED) and
#   waits until each reports SERVING.

BUILD_DIR="${BUILD_DIR:-build}"
DATA_DIR="${DATA_DIR:-${BITEWISE_DATA_DIR:-$PWD/data}}"
BASE_PORT="${BASE_PORT:-${BITEWISE_BASE_PORT:-50051}}"

# A random first port for a test's or benchmark's own six (four services, a
# spare, the console), below Linux's ephemeral range (32768-60999 by
# default), where an outgoing connection of any process may hold a port.
random_base_port() { echo $((20000 + (RANDOM % 1200) * 10)); }
mkdir -p "$DATA_DIR"

# The next simulated plate's number (kept in DATA_DIR): every run gets a
# new plate, seeded by it.
next_plate() {
  local counter="$DATA_DIR/meals.count" n
  n=$(($(cat "$counter" 2>/dev/null || echo 0) + 1))
  echo "$n" >"$counter"
  echo "$n"
}
PIDS=()
stop_services() {
  for pid in "${PIDS[@]}"; do kill -TERM "$pid" 2>/dev/null || true; done
  for pid in "${PIDS[@]}"; do wait "$pid" 2>/dev/null || true; done
  PIDS=()
}

# start_one NAME SERVICE PORT BINARY [ARGS...]
start_one() {
  local name="$1" service="$2" port="$3" binary="$4"
  shift 4
  local log="$DATA_DIR/logs/$name.log"
  local before
  before=$(stat -c %s "$log" 2>/dev/null || echo 0)
  "$binary" --listen "127.0.0.1:$port" "$@" >>"$log" 2>&1 &
  local pid=$!
  PIDS+=("$pid")
  # SERVING from the process started here: another one left on the port
  # (an earlier run killed, a console) would answer too, while this one
  # failed to bind and exited. So this start's own log lines must say it
  # serves (the line may follow the health status by a moment).
  local own=0
  if "$BUILD_DIR"/clients/health/bitewise-health --address "127.0.0.1:$port" \
    --service "bitewise.v1.$service" --timeout_s 60 >/dev/null; then
    for _ in $(seq 50); do
      local fresh from=$((before + 1))
      # A log cut shorter meanwhile (rotated) is read from its start.
      if (($(stat -c %s "$log" 2>/dev/null || echo 0) < before)); then from=1; fi
      fresh=$(tail -c +"$from" "$log" 2>/dev/null || true)
      if [[ $fresh == *"serving on"* ]] && kill -0 "$pid" 2>/dev/null; then
        own=1
        break
      fi
      sleep 0.1
    done
  fi
  if ((!own)); then
    echo "$service did not become healthy; last lines of $DATA_DIR/logs/$name.log:" >&2
    tail -n 20 "$DATA_DIR/logs/$name.log" >&2
    exit 1
  fi
  printf '    %-18s 127.0.0.1:%s  SERVING\n' "$service" "$port"
}

start_services() {
  local seed="$1"
  mkdir -p "$DATA_DIR/logs"
  printf '\n==> Starting the services (logs in %s/logs)\n' "$DATA_DIR"
  start_one bandit BanditService "$BASE_PORT" "$BUILD_DIR"/services/bandit/bitewise-bandit \
    --db "$DATA_DIR/bandit.db" --create
  start_one perception PerceptionService "$((BASE_PORT + 1))" \
    "$BUILD_DIR"/services/perception/bitewise-perception
  start_one haptic HapticService "$((BASE_PORT + 2))" "$BUILD_DIR"/services/haptic/bitewise-haptic
  start_one robot RobotService "$((BASE_PORT + 3))" "$BUILD_DIR"/services/robot/bitewise-robot \
    --backend sim --seed "$seed"
}

# The addresses of the four services, as client flags.
service_flags() {
  echo --bandit "127.0.0.1:$BASE_PORT" --perception "127.0.0.1:$((BASE_PORT + 1))" \
    --haptic "127.0.0.1:$((BASE_PORT + 2))" --robot "127.0.0.1:$((BASE_PORT + 3))"
}
