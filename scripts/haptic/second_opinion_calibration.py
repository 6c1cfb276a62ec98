#!/usr/bin/env python3
"""A second opinion from the familiarity summaries, chosen leave-one-story-out
(docs/haptic.md, "A second opinion from the summaries").

The familiarity model (familiarity.h) is one Gaussian per class over ten
physical summaries of HapticNet's window. Read as a classifier (quadratic
discriminant, equal priors), it gives its own probabilities q from the
squared distances d_c to each class and the classes' precisions P_c:
log q_c = (-d_c / 2 + log det(P_c) / 2) / tau, normalised. It is a model of
another kind than the network, so where the two disagree the mixture
p' = (1 - w) p + w q hedges.

Reads what leave_one_story_out.sh writes: for every story h, the model
trained without h (<h>.onnx.familiarity beside it) and its probabilities and
class distances on h's tuning items (<h>.tune.csv, seed 7) and report items
(<h>.report.csv, seed 20261123). For story h, (w, tau) is chosen on the OTHER
stories' tuning items only (smallest pooled log loss), then scored on h's
report items, so nothing of h chooses it. The grids were fixed before any
run: w in 0, 0.1, ..., 0.6; tau in 1, 2, 4, 8, 16, 32.

usage: second_opinion_calibration.py DIR STORY...
"""
import csv
import math
import sys

import numpy as np

from story_calibration import CLASSES, scores
from unfamiliar_calibration import nll, pooled, row

W_GRID = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6]
TAU_GRID = [1.0, 2.0, 4.0, 8.0, 16.0, 32.0]


def log_dets(path):
    """log det of each class's precision, from a familiarity file."""
    dets = {}
    with open(path) as f:
        for line in f:
            fields = line.split()
            if fields[:2] == ["bitewise-haptic-familiarity", "2"]:
                sys.exit(f"{path}: a familiarity file with one Gaussian per "
                         "class and story (version 2); this study needs one "
                         "per class (train with --familiarity_gaussians=class)")
            if fields and fields[0] == "precision":
                values = np.array([float(v) for v in fields[2:]])
                k = int(round(math.sqrt(len(values))))
                sign, logdet = np.linalg.slogdet(values.reshape(k, k))
                if sign <= 0:
                    sys.exit(f"{path}: class {fields[1]}'s precision is not "
                             "positive definite")
                dets[int(fields[1])] = logdet
    return np.array([dets[c] for c in range(len(CLASSES))])


def load(path, logdet):
    labels, probabilities, ll = [], [], []
    with open(path) as f:
        for r in csv.DictReader(f):
            labels.append(CLASSES.index(r["label"]))
            probabilities.append([float(r["p_" + c]) for c in CLASSES])
            d = np.array([float(r["d_" + c]) for c in CLASSES])
            ll.append(-0.5 * d + 0.5 * logdet)
    return np.array(labels), np.array(probabilities), np.array(ll)


def second_opinion(ll, tau):
    z = ll / tau
    z = z - z.max(axis=1, keepdims=True)
    q = np.exp(z)
    return q / q.sum(axis=1, keepdims=True)


def mix(p, ll, w, tau):
    return (1.0 - w) * p + w * second_opinion(ll, tau)


def has_class_distances(directory, h):
    try:
        with open(f"{directory}/{h}.tune.csv") as f:
            r = next(csv.DictReader(f), None)
        open(f"{directory}/{h}.onnx.familiarity").close()
    except OSError:
        return False
    return r is not None and bool(r.get("d_hard"))


def main():
    directory, stories = sys.argv[1], sys.argv[2:]
    if not all(has_class_distances(directory, h) for h in stories):
        print("no class distances (a model without a familiarity file, such "
              "as an ensemble): the second-opinion study is skipped")
        return
    logdet = {h: log_dets(f"{directory}/{h}.onnx.familiarity")
              for h in stories}
    tune = {h: load(f"{directory}/{h}.tune.csv", logdet[h]) for h in stories}
    report = {h: load(f"{directory}/{h}.report.csv", logdet[h])
              for h in stories}

    print("The summaries' Gaussians alone (tau 1) on each held-out story's "
          "report items:")
    print("| held out | accuracy | hard | medium | soft | hard-skin |")
    print("|---|---:|---:|---:|---:|---:|")
    for h in stories:
        y, _, ll = report[h]
        s = scores(y, second_opinion(ll, 1.0))
        print(f"| {h} | {100 * s['accuracy']:.1f} % | " +
              " | ".join(f"{100 * a:.1f}" for a in s["per_class"]) + " |")
    print()
    print("| held out, rule (chosen on the other stories) | accuracy | hard | "
          "medium | soft | hard-skin | ECE | over-confidence: hard | medium | "
          "soft | hard-skin | log loss |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for h in stories:
        ty, tp, tl = pooled(tune, [g for g in stories if g != h])
        losses = {(w, tau): nll(ty, mix(tp, tl, w, tau))
                  for w in W_GRID for tau in TAU_GRID}
        w, tau = min(losses, key=losses.get)
        y, p, ll = report[h]
        print(row(f"{h}: as is", scores(y, p)))
        print(row(f"{h}: mixed (w {w:.1f}, tau {tau:g})",
                  scores(y, mix(p, ll, w, tau))))
    print()
    print("Tuning log loss of the other stories pooled, per fold, for each w "
          "at its best tau:")
    for h in stories:
        ty, tp, tl = pooled(tune, [g for g in stories if g != h])
        cells = []
        for w in W_GRID:
            best = min(TAU_GRID, key=lambda t: nll(ty, mix(tp, tl, w, t)))
            cells.append(f"w {w:.1f}: {nll(ty, mix(tp, tl, w, best)):.3f} "
                         f"(tau {best:g})")
        print(f"  {h}: " + "; ".join(cells))


if __name__ == "__main__":
    main()
