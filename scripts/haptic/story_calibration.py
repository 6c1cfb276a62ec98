#!/usr/bin/env python3
"""Leave-one-story-out calibration of HapticNet (docs/haptic.md).

Reads, for every trace story h, the probabilities that the model trained
without h gives on h's traces, twice: on tuning items (--tuning_seed of
bitewise-haptic-eval) and on report items (--report_seed). Chooses a softmax
temperature per fold on its tuning items (the one with the smallest log
loss), and for the report on story h uses the median of the OTHER folds'
temperatures, so nothing of story h (neither tuning nor report items) chooses
the temperature h is reported with. Prints the markdown tables of
docs/haptic.md and the temperature for a model trained on every story but
one held out (the median over all folds).

usage: story_calibration.py DIR STORY...   (DIR holds <story>.tune.csv and
       <story>.report.csv as bitewise-haptic-eval --probabilities_csv writes)
"""
import csv
import math
import sys

import numpy as np

CLASSES = ["hard", "medium", "soft", "hard_skin"]


def load(path):
    labels, probabilities = [], []
    with open(path) as f:
        for row in csv.DictReader(f):
            labels.append(CLASSES.index(row["label"]))
            probabilities.append([float(row["p_" + c]) for c in CLASSES])
    return np.array(labels), np.array(probabilities)


def temper(p, t):
    logits = np.log(np.maximum(p, 1e-300)) / t
    logits -= logits.max(axis=1, keepdims=True)
    e = np.exp(logits)
    return e / e.sum(axis=1, keepdims=True)


def scores(y, p):
    predicted = p.argmax(axis=1)
    top = p.max(axis=1)
    right = predicted == y
    per_class = [right[y == k].mean() for k in range(4)]
    over = [top[y == k].mean() - right[y == k].mean() for k in range(4)]
    ece = 0.0
    bins = np.minimum((top * 10).astype(int), 9)
    for b in range(10):
        m = bins == b
        if m.any():
            ece += abs(top[m].sum() - right[m].sum()) / len(y)
    nll = -np.mean(np.log(np.maximum(p[np.arange(len(y)), y], 1e-12)))
    return dict(accuracy=right.mean(), per_class=per_class, over=over,
                ece=ece, nll=nll)


GRID = np.exp(np.linspace(math.log(0.5), math.log(10.0), 121))


def best_temperature(y, p):
    return min(GRID, key=lambda t: scores(y, temper(p, t))["nll"])


def main():
    directory, stories = sys.argv[1], sys.argv[2:]
    tuned = {}
    for h in stories:
        y, p = load(f"{directory}/{h}.tune.csv")
        tuned[h] = best_temperature(y, p)
    print("| held out | T on its own tuning items (not used for it) | "
          "T used (median of the other folds) |")
    print("|---|---:|---:|")
    used = {}
    for h in stories:
        used[h] = float(np.median([tuned[g] for g in stories if g != h]))
        print(f"| {h} | {tuned[h]:.2f} | {used[h]:.2f} |")
    print()
    print("| held out | accuracy | hard | medium | soft | hard-skin | ECE at T=1 "
          "| ECE | over-confidence: hard | medium | soft | hard-skin | "
          "log loss |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for h in stories:
        y, p = load(f"{directory}/{h}.report.csv")
        raw = scores(y, p)
        s = scores(y, temper(p, used[h]))
        cells = [f"{100 * s['accuracy']:.1f} %"]
        cells += [f"{100 * a:.1f}" for a in s["per_class"]]
        cells += [f"{raw['ece']:.3f}", f"{s['ece']:.3f}"]
        cells += [f"{o:+.3f}" for o in s["over"]]
        cells += [f"{s['nll']:.3f}"]
        print(f"| {h} (T {used[h]:.2f}) | " + " | ".join(cells) + " |")
    print()
    print("At T = 1 (the trainer's rule: never sharpen), on the report items:")
    print("| held out | ECE | over-confidence: hard | medium | soft | hard-skin |")
    print("|---|---:|---:|---:|---:|---:|")
    for h in stories:
        y, p = load(f"{directory}/{h}.report.csv")
        raw = scores(y, p)
        print(f"| {h} | {raw['ece']:.3f} | "
              + " | ".join(f"{o:+.3f}" for o in raw["over"]) + " |")
    print()
    print(f"temperature for a model trained on all but one story: "
          f"{float(np.median(list(tuned.values()))):.2f} (median of "
          + ", ".join(f"{h} {tuned[h]:.2f}" for h in stories) + ")")


if __name__ == "__main__":
    main()
