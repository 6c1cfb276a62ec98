#!/usr/bin/env python3
"""Chooses a training setting leave-one-story-out, by the other stories only
(docs/haptic.md, "A slower approach").

Each candidate setting is a directory written by leave_one_story_out.sh with
that setting: for every story h, <h>.tune.csv (tuning items, seed 7) and
<h>.report.csv (report items, seed 20261123), the probabilities of the model
trained without h. For held-out story h the setting is the one with the
smallest log loss on the OTHER stories' tuning items (the mean over those
folds), so nothing of h chooses it; h is then reported on its report items
with the chosen setting. Probabilities are taken as the models give them
(T = 1: the trainer's own temperature, never below 1).

usage: choose_by_other_stories.py STORIES NAME=DIR [NAME=DIR ...]
       (STORIES comma-separated, e.g. world,piecewise,mechanics,compliant)
"""
import sys

import numpy as np

from story_calibration import load, scores


def main():
    stories = sys.argv[1].split(",")
    settings = dict(arg.split("=", 1) for arg in sys.argv[2:])
    tune = {(name, h): scores(*load(f"{d}/{h}.tune.csv"))["nll"]
            for name, d in settings.items() for h in stories}
    print("Tuning log loss (seed 7) of each fold, by setting:")
    print("| setting | " + " | ".join(stories) + " |")
    print("|---|" + "---:|" * len(stories))
    for name in settings:
        print(f"| {name} | "
              + " | ".join(f"{tune[name, h]:.3f}" for h in stories) + " |")
    print()
    print("| held out (setting chosen by the others) | accuracy | hard | medium "
          "| soft | hard-skin | ECE | over-confidence: hard | medium | soft | "
          "hard-skin | log loss |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for h in stories:
        others = [g for g in stories if g != h]
        chosen = min(settings,
                     key=lambda n: np.mean([tune[n, g] for g in others]))
        s = scores(*load(f"{settings[chosen]}/{h}.report.csv"))
        cells = [f"{100 * s['accuracy']:.1f} %"]
        cells += [f"{100 * a:.1f}" for a in s["per_class"]]
        cells += [f"{s['ece']:.3f}"]
        cells += [f"{o:+.3f}" for o in s["over"]]
        cells += [f"{s['nll']:.3f}"]
        print(f"| {h} ({chosen}) | " + " | ".join(cells) + " |")
    print()
    print("Every setting on every fold's report items (not used to choose):")
    print("| setting | held out | accuracy | hard | medium | soft | hard-skin "
          "| ECE | over-confidence: hard | medium | soft | hard-skin |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for name, d in settings.items():
        for h in stories:
            s = scores(*load(f"{d}/{h}.report.csv"))
            cells = [f"{100 * s['accuracy']:.1f} %"]
            cells += [f"{100 * a:.1f}" for a in s["per_class"]]
            cells += [f"{s['ece']:.3f}"]
            cells += [f"{o:+.3f}" for o in s["over"]]
            print(f"| {name} | {h} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
