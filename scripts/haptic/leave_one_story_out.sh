#!/usr/bin/env bash
# Leave one story out (docs/haptic.md, "Held-out stories"): for every trace
# story, trains HapticNet on the other stories, evaluates it the way the
# service runs it on the story it never saw (tuning items, seed 7, and report
# items, seed 20261123), then chooses each fold's softmax temperature from
# the OTHER folds' tuning items and prints the tables of docs/haptic.md.
#
#   scripts/haptic/leave_one_story_out.sh OUT_DIR
#       [--ensemble|--single_story_ensemble|--seed_ensemble]
#                                          [--train_also=LIST] [trainer flags...]
#   e.g. scripts/haptic/leave_one_story_out.sh /tmp/loso --augment
#
# --ensemble: each fold's model is the ensemble of the models trained on its
# training stories but one, one member per training story (with four folds:
# every pair of its three; docs/haptic.md, "An ensemble over stories"); each
# member is trained once into OUT_DIR/pairs (six with four folds, fifteen with
# six).
# --single_story_ensemble: each fold's model is the ensemble of the models
# trained on one of its training stories each, trained into OUT_DIR/singles.
# --seed_ensemble: each fold's model is the ensemble of three models trained
# on its three training stories with seeds 1, 2 and 3 (traces, split, initial
# weights, batch order), trained into OUT_DIR/seeds.
# --train_also=LIST: stories every fold also trains on and none holds out
# (e.g. puncture; docs/haptic.md, "A fourth training story").
#
# LOSO_STORIES=a,b,...: the stories of the folds (default the four above).
# About 5 minutes per story on one core. Needs a build (scripts/setup.sh).
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT="${1:?usage: scripts/haptic/leave_one_story_out.sh OUT_DIR [trainer flags...]}"
shift
ENSEMBLE=0
SEED_ENSEMBLE=0
SINGLES=0
if [ "${1:-}" = "--ensemble" ]; then ENSEMBLE=1; shift; fi
if [ "${1:-}" = "--single_story_ensemble" ]; then SINGLES=1; shift; fi
if [ "${1:-}" = "--seed_ensemble" ]; then SEED_ENSEMBLE=1; shift; fi
ALSO=""
if [[ "${1:-}" == --train_also=* ]]; then ALSO="${1#--train_also=}"; shift; fi
BUILD_DIR="${BUILD_DIR:-build}"
TRAIN="$BUILD_DIR/services/haptic/bitewise-haptic-train"
# The fold models' familiarity files: one Gaussian per class, as in every
# documented run (and as unfamiliar_calibration.py and
# second_opinion_calibration.py read them); a trainer flag after OUT_DIR
# overrides it.
FAMILIARITY=(--familiarity_gaussians=class)
# The folds: the four stories of the tables, or LOSO_STORIES (comma-separated,
# e.g. all six with puncture and poroelastic).
IFS=, read -r -a STORIES <<<"${LOSO_STORIES:-world,piecewise,mechanics,compliant}"
mkdir -p "$OUT"
for held in "${STORIES[@]}"; do
  others=$(printf '%s\n' "${STORIES[@]}" | grep -vx "$held" | paste -sd,)
  if [ -n "$ALSO" ]; then
    if [ "$ENSEMBLE" = 1 ] || [ "$SINGLES" = 1 ]; then
      echo "--train_also does not combine with a story ensemble" >&2
      exit 2
    fi
    others="$others,$ALSO"
  fi
  if [ ! -f "$OUT/$held.onnx" ] && { [ "$ENSEMBLE" = 1 ] || [ "$SINGLES" = 1 ]; }; then
    # One member per training story g: with --ensemble trained on the fold's
    # training stories but g, named by its stories in the folds' order (so
    # the model without h and g is trained once and shared by the folds of h
    # and of g); with --single_story_ensemble trained on g alone.
    IFS=, read -r -a training <<<"$others"
    members=()
    for g in "${training[@]}"; do
      if [ "$ENSEMBLE" = 1 ]; then
        dir="$OUT/pairs"
        name=$(printf '%s\n' "${training[@]}" | grep -vx "$g" | paste -sd+)
      else
        dir="$OUT/singles"
        name="$g"
      fi
      mkdir -p "$dir"
      if [ ! -f "$dir/$name.onnx" ]; then
        echo "==> training on ${name//+/, }"
        "$TRAIN" --stories="${name//+/,}" --held_out_per_class=0 "${FAMILIARITY[@]}" "$@" \
          --out="$dir/$name.onnx" >"$dir/$name.log"
      fi
      members+=("$dir/$name.onnx")
    done
    echo "==> the ensemble of ${#members[@]} members on $others (holding out $held)"
    "$TRAIN" --ensemble_of="$(IFS=,; echo "${members[*]}")" --out="$OUT/$held.onnx" \
      >"$OUT/$held.train.log"
  elif [ ! -f "$OUT/$held.onnx" ] && [ "$SEED_ENSEMBLE" = 1 ]; then
    mkdir -p "$OUT/seeds"
    members=()
    for seed in 1 2 3; do
      member="$OUT/seeds/$held-seed$seed.onnx"
      if [ ! -f "$member" ]; then
        echo "==> training on $others with seed $seed (holding out $held)"
        "$TRAIN" --stories="$others" --seed="$seed" "${FAMILIARITY[@]}" "$@" --out="$member" \
          >"$OUT/seeds/$held-seed$seed.log"
      fi
      members+=("$member")
    done
    echo "==> the ensemble of seeds 1-3 on $others (holding out $held)"
    "$TRAIN" --ensemble_of="$(IFS=,; echo "${members[*]}")" --out="$OUT/$held.onnx" \
      >"$OUT/$held.train.log"
  elif [ ! -f "$OUT/$held.onnx" ]; then
    echo "==> training on $others (holding out $held)"
    "$TRAIN" --stories="$others" "${FAMILIARITY[@]}" "$@" --out="$OUT/$held.onnx" >"$OUT/$held.train.log"
  fi
  for part in tune:7 report:20261123; do
    "$BUILD_DIR"/services/haptic/bitewise-haptic-eval --model="$OUT/$held.onnx" \
      --stories="$held" --seed="${part#*:}" \
      --probabilities_csv="$OUT/$held.${part%%:*}.csv" >"$OUT/$held.${part%%:*}.log"
    if [ "$ENSEMBLE" = 1 ]; then
      # Each member alone, for the disagreement study below.
      mkdir -p "$OUT/members"
      IFS=, read -r -a training <<<"$others"
      for g in "${training[@]}"; do
        subset=$(printf '%s\n' "${training[@]}" | grep -vx "$g" | paste -sd+)
        "$BUILD_DIR"/services/haptic/bitewise-haptic-eval \
          --model="$OUT/pairs/$subset.onnx" --stories="$held" --seed="${part#*:}" \
          --probabilities_csv="$OUT/members/$held.without-$g.${part%%:*}.csv" \
          >"$OUT/members/$held.without-$g.${part%%:*}.log"
      done
    fi
  done
done
# Debian's python3 (python3-numpy, which scripts/setup.sh installs) first.
PYTHON=python3
if [ -x /usr/bin/python3 ]; then PYTHON=/usr/bin/python3; fi
"$PYTHON" scripts/haptic/story_calibration.py "$OUT" "${STORIES[@]}"
# The familiarity-dependent flattening, chosen the same way (docs/haptic.md,
# "Confidence that falls with familiarity").
"$PYTHON" scripts/haptic/unfamiliar_calibration.py "$OUT" "${STORIES[@]}"
# The summaries' Gaussians as a second opinion mixed in, chosen the same way
# ("A second opinion from the summaries").
"$PYTHON" scripts/haptic/second_opinion_calibration.py "$OUT" "${STORIES[@]}"
# The story ensemble's members' disagreement, chosen the same way
# ("Ensembles on the six folds").
if [ "$ENSEMBLE" = 1 ]; then
  "$PYTHON" scripts/haptic/disagreement_calibration.py "$OUT" "${STORIES[@]}"
fi
