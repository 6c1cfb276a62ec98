#!/usr/bin/env python3
"""Confidence that falls with familiarity, chosen leave-one-story-out
(docs/haptic.md, "Honest confidence on unfamiliar traces").

Reads what leave_one_story_out.sh writes: for every story h, the
probabilities and the familiarity distance that the model trained without h
(and the familiarity model fitted with it) gives on h's tuning items
(<h>.tune.csv, seed 7) and report items (<h>.report.csv, seed 20261123).

Each rule maps a trace's probabilities p and familiarity distance D (the
smallest squared Mahalanobis distance to a class, familiarity.h) to new
probabilities. Its parameters for story h are chosen on the OTHER stories'
tuning items only (smallest log loss, pooled), then scored on h's report
items, so nothing of h chooses them:

  as is      p unchanged (the shipped rule);
  temper     p ** (1/T), T the median of the other folds' best temperatures
             (story_calibration.py's rule);
  flatten    (1 - u) p + u / 4 with u = sigmoid(a + b ln D): the farther the
             trace lies from what the model was fitted on, the closer to
             uniform.

usage: unfamiliar_calibration.py DIR STORY...
"""
import csv
import math
import sys

import numpy as np

from story_calibration import CLASSES, scores, temper


def load(path):
    labels, probabilities, distances = [], [], []
    with open(path) as f:
        for row in csv.DictReader(f):
            labels.append(CLASSES.index(row["label"]))
            probabilities.append([float(row["p_" + c]) for c in CLASSES])
            distances.append(float(row["distance"]))
    return (np.array(labels), np.array(probabilities),
            np.log(np.maximum(np.array(distances), 1e-12)))


def pooled(tune, stories):
    """The three arrays of every story's tuning items in `stories`, pooled."""
    return tuple(np.concatenate([tune[g][i] for g in stories])
                 for i in range(3))


def flatten(p, log_d, a, b):
    u = 1.0 / (1.0 + np.exp(-(a + b * log_d)))
    return (1.0 - u)[:, None] * p + (u / 4.0)[:, None]


def nll(y, p):
    return -np.mean(np.log(np.maximum(p[np.arange(len(y)), y], 1e-12)))


T_GRID = np.exp(np.linspace(math.log(0.5), math.log(10.0), 121))
A_GRID = np.linspace(-16.0, 4.0, 81)
B_GRID = np.linspace(0.0, 4.0, 41)


def best_temperature(y, p):
    return min(T_GRID, key=lambda t: nll(y, temper(p, t)))


def best_flatten(y, p, log_d):
    best = (math.inf, 0.0, 0.0)
    for a in A_GRID:
        for b in B_GRID:
            loss = nll(y, flatten(p, log_d, a, b))
            if loss < best[0]:
                best = (loss, a, b)
    return best[1], best[2]


def row(name, s):
    cells = [f"{100 * s['accuracy']:.1f} %"]
    cells += [f"{100 * a:.1f}" for a in s["per_class"]]
    cells += [f"{s['ece']:.3f}"]
    cells += [f"{o:+.3f}" for o in s["over"]]
    cells += [f"{s['nll']:.3f}"]
    return f"| {name} | " + " | ".join(cells) + " |"


def print_quantiles(what, report, stories, fmt):
    """A table of ln-stored per-trace values (report[h][2]) on the report
    items: median and 90th percentile per story and true category."""
    print(f"{what} on the report items (median, 90th percentile), per true "
          "category:")
    print("| held out | hard | medium | soft | hard-skin |")
    print("|---|---:|---:|---:|---:|")
    for h in stories:
        y, _, log_d = report[h]
        d = np.exp(log_d)
        print(f"| {h} | " + " | ".join(
            f"{np.median(d[y == k]):{fmt}} / {np.quantile(d[y == k], 0.9):{fmt}}"
            for k in range(4)) + " |")
    print()


def print_rules_header():
    print("| held out, rule (parameters, chosen on the other stories) | "
          "accuracy | hard | medium | soft | hard-skin | ECE | "
          "over-confidence: hard | medium | soft | hard-skin | log loss |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")


def has_distances(path):
    with open(path) as f:
        row = next(csv.DictReader(f), None)
    return row is not None and bool(row.get("distance"))


def main():
    directory, stories = sys.argv[1], sys.argv[2:]
    if not all(has_distances(f"{directory}/{h}.tune.csv") for h in stories):
        print("no familiarity distances (a model without a familiarity file, "
              "such as an ensemble): the flattening study is skipped")
        return
    tune = {h: load(f"{directory}/{h}.tune.csv") for h in stories}
    report = {h: load(f"{directory}/{h}.report.csv") for h in stories}
    own_t = {h: best_temperature(tune[h][0], tune[h][1]) for h in stories}

    print_quantiles("Familiarity distance", report, stories, ".0f")
    print_rules_header()
    for h in stories:
        others = [g for g in stories if g != h]
        y, p, log_d = report[h]
        print(row(f"{h}: as is", scores(y, p)))
        t = float(np.median([own_t[g] for g in others]))
        print(row(f"{h}: temper (T {t:.2f})", scores(y, temper(p, t))))
        ty, tp, tl = pooled(tune, others)
        a, b = best_flatten(ty, tp, tl)
        print(row(f"{h}: flatten (a {a:.2f}, b {b:.2f})",
                  scores(y, flatten(p, log_d, a, b))))
    ty, tp, tl = pooled(tune, stories)
    a, b = best_flatten(ty, tp, tl)
    print()
    print(f"flatten chosen on every story's tuning items: a {a:.2f}, "
          f"b {b:.2f} (u = 0.5 at D = {math.exp(-a / b) if b else math.inf:.0f})")


if __name__ == "__main__":
    main()
