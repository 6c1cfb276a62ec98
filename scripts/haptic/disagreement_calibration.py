#!/usr/bin/env python3
"""Confidence that falls with the members' disagreement, chosen
leave-one-story-out (docs/haptic.md, "Ensembles on the six folds").

Reads what leave_one_story_out.sh --ensemble writes for every story h: the
ensemble's probabilities on h's tuning items (<h>.tune.csv, seed 7) and
report items (<h>.report.csv, seed 20261123), and each member's alone,
<DIR>/members/<h>.without-<g>.<part>.csv for every other story g (the member
trained on all stories but h and g; bitewise-haptic-eval --probabilities_csv).

The disagreement of a trace is D = mean over members of KL(p_i || p_mean),
the information the member's identity carries about the class: near 0 where
the members agree, large where models that saw different stories read the
trace differently. The rule pulls the mean towards uniform as D grows,

  disagree   (1 - u) p_mean + u / 4 with u = sigmoid(a + b ln D),

with (a, b) chosen on the OTHER stories' tuning items only (smallest log
loss, pooled), then scored on h's report items beside the mean as it is.

usage: disagreement_calibration.py DIR STORY...
"""
import sys

import numpy as np

from story_calibration import load, scores
from unfamiliar_calibration import (best_flatten, flatten, pooled,
                                    print_quantiles, print_rules_header, row)


def disagreement(members, mean):
    """The members' mean KL divergence from their mean, per trace."""
    eps = 1e-12
    kl = [np.sum(p * (np.log(np.maximum(p, eps)) -
                      np.log(np.maximum(mean, eps))), axis=1)
          for p in members]
    return np.mean(kl, axis=0)


def fold(directory, h, stories, part):
    """Labels, ensemble probabilities and ln D of fold h's items."""
    y, p = load(f"{directory}/{h}.{part}.csv")
    members = []
    for g in stories:
        if g == h:
            continue
        y_g, p_g = load(f"{directory}/members/{h}.without-{g}.{part}.csv")
        if not np.array_equal(y_g, y):
            sys.exit(f"{h}.without-{g}.{part}.csv: other items than {h}.{part}.csv")
        members.append(p_g)
    mean = np.mean(members, axis=0)
    gap = np.max(np.abs(mean - p))
    if gap > 1e-5:
        sys.exit(f"{h}.{part}: the members' mean differs from the ensemble's "
                 f"probabilities by {gap:.2e}")
    return y, p, np.log(np.maximum(disagreement(members, p), 1e-12))


def main():
    directory, stories = sys.argv[1], sys.argv[2:]
    tune = {h: fold(directory, h, stories, "tune") for h in stories}
    report = {h: fold(directory, h, stories, "report") for h in stories}
    print_quantiles("Disagreement D", report, stories, ".3f")
    print_rules_header()
    for h in stories:
        others = [g for g in stories if g != h]
        a, b = best_flatten(*pooled(tune, others))
        y, p, log_d = report[h]
        print(row(f"{h}: as is", scores(y, p)))
        print(row(f"{h}: disagree (a {a:.2f}, b {b:.2f})",
                  scores(y, flatten(p, log_d, a, b))))


if __name__ == "__main__":
    main()
