#!/usr/bin/env python3
"""What the first 50 ms after contact look like, per story and class
(docs/haptic.md, "Why a slow approach did not help: the arm's compliance").

For each trace of each CSV (the trainer's format; write a story's traces with
bitewise-haptic-train --stories=S --traces_per_class=N --seed=7
--write_traces=S.csv --write_traces_only), the force is tared by the median
of its first 50 ms, and contact is the first sample whose force norm reaches
1 N and stays at least 0.5 N for 3 ms (the service's thresholds, without its
back-extrapolation of the rising edge). Within the 50 ms after contact it
measures:
  - peak: the largest force norm (N);
  - rise rate: 0.8 x peak over the time to first reach 0.8 x peak (N/s);
  - drop: the largest loss after the peak, as a share of the peak.
Prints the 10th, 50th and 90th percentiles per class.

usage: window_shapes.py NAME=TRACES.csv [NAME=TRACES.csv ...]
       window_shapes.py --by_drop TRACES.csv PROBABILITIES.csv CLASS OTHER
The second form takes a model's probabilities on the same traces
(bitewise-haptic-eval --stories=S --seed=7 --traces_per_class=N
--probabilities_csv=FILE, in the same order) and prints, for the traces of
CLASS in bins of their drop, the share the model calls OTHER.
"""
import csv
import sys

import numpy as np

CLASSES = ["hard", "medium", "soft", "hard_skin"]


def traces(path):
    rows = {}
    with open(path) as f:
        for r in csv.DictReader(f):
            rows.setdefault(r["trace"], (r["label"], []))[1].append(
                [float(r[k]) for k in ("t_s", "fx_n", "fy_n", "fz_n")])
    for label, samples in rows.values():
        yield label, np.array(samples)


def window_shape(samples, window_s=0.05):
    t = samples[:, 0]
    force = samples[:, 1:4]
    force = force - np.median(force[t < t[0] + 0.05], axis=0)
    norm = np.linalg.norm(force, axis=1)
    for k in np.flatnonzero(norm >= 1.0):
        hold = (t >= t[k]) & (t < t[k] + 0.003)
        if (norm[hold] >= 0.5).all():
            break
    else:
        return None
    inside = (t >= t[k]) & (t < t[k] + window_s)
    tw, fw = t[inside], norm[inside]
    top = int(np.argmax(fw))
    reach = int(np.argmax(fw >= 0.8 * fw[top]))
    rate = 0.8 * fw[top] / max(tw[reach] - t[k], 1e-4)
    drop = (fw[top] - fw[top:].min()) / fw[top]
    return fw[top], rate, drop


def by_drop(traces_csv, probabilities_csv, label, other):
    with open(probabilities_csv) as f:
        rows = list(csv.DictReader(f))
    drops, called = [], []
    for (true, samples), row in zip(traces(traces_csv), rows):
        if true != row["label"]:
            sys.exit("the probabilities are not of these traces, in this order")
        shape = window_shape(samples)
        if true != label or shape is None:
            continue
        p = [float(row["p_" + c]) for c in CLASSES]
        drops.append(shape[2])
        called.append(CLASSES[int(np.argmax(p))] == other)
    drops, called = np.array(drops), np.array(called)
    print(f"| drop of a {label} item | items | called {other} |")
    print("|---|---:|---:|")
    edges = [0.0, 0.2, 0.25, 0.3, 0.35, 0.4, 1.01]
    for lo, hi in zip(edges, edges[1:]):
        inside = (drops >= lo) & (drops < hi)
        share = 100 * called[inside].mean() if inside.any() else 0.0
        print(f"| {lo:.2f}-{min(hi, 1.0):.2f} | {inside.sum()} | {share:.0f} % |")


def main():
    if sys.argv[1] == "--by_drop":
        by_drop(*sys.argv[2:6])
        return
    print("| story | class | peak (N) 10 / 50 / 90 % | rise rate (N/s) | "
          "drop after the peak |")
    print("|---|---|---|---|---|")
    for arg in sys.argv[1:]:
        name, path = arg.split("=", 1)
        shapes = {c: [] for c in CLASSES}
        for label, samples in traces(path):
            shape = window_shape(samples)
            if shape is not None:
                shapes[label].append(shape)
        for c in CLASSES:
            v = np.array(shapes[c])
            q = lambda j, fmt: " / ".join(
                format(x, fmt) for x in np.percentile(v[:, j], [10, 50, 90]))
            print(f"| {name} | {c} | {q(0, '.1f')} | {q(1, '.0f')} | "
                  f"{q(2, '.2f')} |")


if __name__ == "__main__":
    main()
