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

scripts/setup.sh --meal

# shellcheck source=scripts/lib/services.sh
source scripts/lib/services.sh
MEAL_NUMBER=$(next_plate)
if [ -z "$MEAL" ]; then MEAL="meal-$MEAL_NUMBER"; fi
trap stop_services EXIT
start_services "$MEAL_NUMBER"

printf '\n==> Meal %s for user %s (simulated plate %d)\n' "$MEAL" "$USER_ID" "$MEAL_NUMBER"
status=0
# shellcheck disable=SC2046
build/clients/orchestrator/bitewise-orchestrator --user "$USER_ID" --meal "$MEAL" \
  $(service_flags) --journal "$DATA_DIR/orchestrator.journal" "${EXTRA[@]}" || status=$?

printf '\n==> Stopping the services\n'
stop_services
trap - EXIT
if [ "$status" -eq 0 ]; then
  echo "done; run scripts/meal.sh --user $USER_ID again to continue learning"
fi
exit "$status"
