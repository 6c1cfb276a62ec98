#!/usr/bin/env python3
"""Summarises scripts/experiments/meals_compare.sh's meals.tsv.

Each line: pair, meal, learner (posthoc, polinucb or vision), attempts,
failures. Arguments: the file, users, meals, and the arms compared with
vision only (comma separated; default posthoc). Prints, per arm, per meal
and over all meals, the mean failures of the arm and of vision only over
the pairs with a 95% t interval, and the paired difference (vision minus
the arm: positive means the arm failed less). Pairs missing a meal of
either arm are left out of that meal's row, and said so.
"""
import math
import sys

# Two-sided 95% quantiles of Student's t, degrees of freedom 1..30.
T975 = [12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262,
        2.228, 2.201, 2.179, 2.160, 2.145, 2.131, 2.120, 2.110, 2.101,
        2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056, 2.052,
        2.048, 2.045, 2.042]


def interval(values):
    n = len(values)
    mean = sum(values) / n
    if n < 2:
        return mean, float("nan")
    var = sum((v - mean) ** 2 for v in values) / (n - 1)
    t = T975[n - 2] if n - 1 <= len(T975) else 1.960
    return mean, t * math.sqrt(var / n)


def fmt(values):
    mean, half = interval(values)
    return "%6.2f [%6.2f, %6.2f]" % (mean, mean - half, mean + half)


LABELS = {"posthoc": "post hoc (logprob)", "polinucb": "poLinUCB (logprob)"}


def main():
    path, users, meals = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    # The arms compared with vision only, each paired with it.
    arms = sys.argv[4].split(",") if len(sys.argv) > 4 else ["posthoc"]
    rows = {}
    for line in open(path):
        pair, meal, learner, attempts, failures = line.split()
        rows[(int(pair), int(meal), learner)] = (int(attempts), int(failures))
    print("Failures per meal (8 unseen foods, each until picked up), mean "
          "over user pairs and 95%% t interval; %d pairs x %d meals.\n"
          % (users, meals))
    for arm in arms:
        summarise(rows, users, meals, arm)
    missing = [k for k in
               ((p, m, l) for p in range(1, users + 1)
                for m in range(1, meals + 1) for l in arms + ["vision"])
               if k not in rows]
    if missing:
        print("\nmissing meals (pair, meal, learner): %s" % missing)


def summarise(rows, users, meals, arm):
    label = LABELS.get(arm, arm)
    print("%-6s %5s  %-26s %-26s %-28s %s" % (
        "meal", "pairs", label, "vision only",
        "paired: vision - " + arm, "attempts %s / vision" % arm))
    total_ph, total_vi = {}, {}
    for meal in list(range(1, meals + 1)) + ["all"]:
        ph, vi, att_ph, att_vi = [], [], [], []
        for pair in range(1, users + 1):
            if meal == "all":
                if pair not in total_ph or len(total_ph[pair]) != meals:
                    continue
                ph.append(sum(f for _, f in total_ph[pair]))
                vi.append(sum(f for _, f in total_vi[pair]))
                att_ph.append(sum(a for a, _ in total_ph[pair]))
                att_vi.append(sum(a for a, _ in total_vi[pair]))
                continue
            a = rows.get((pair, meal, arm))
            b = rows.get((pair, meal, "vision"))
            if a is None or b is None:
                continue
            total_ph.setdefault(pair, []).append(a)
            total_vi.setdefault(pair, []).append(b)
            ph.append(a[1])
            vi.append(b[1])
            att_ph.append(a[0])
            att_vi.append(b[0])
        if not ph:
            print("%-6s %5d  (no complete pairs)" % (meal, 0))
            continue
        print("%-6s %5d  %-26s %-26s %-28s %.1f / %.1f" % (
            meal, len(ph), fmt(ph), fmt(vi),
            fmt([v - p for p, v in zip(ph, vi)]),
            sum(att_ph) / len(att_ph), sum(att_vi) / len(att_vi)))
    print()


if __name__ == "__main__":
    main()
