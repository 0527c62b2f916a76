#!/usr/bin/env python3
"""The rule that picks each worst-case method's risk parameter (docs/results/worst-case-methods.md),
from the tuning sweeps' cells.csv (TUNE/<task>/<algo>/cells.csv, metric: the worst return over the
last 10 epochs, mean over the tuning seeds 100-101):

1. on each tuning task, rank the method's values by that mean, best (highest) first: 1, 2, 3;
2. pick the value with the lowest sum of ranks over the two tasks;
3. a tie goes to the value ranked better on Goal_Point (the GUARD task of the two), and a tie
   there to the grid's middle value, then the smaller value.

A cell with a missing or unfinished seed stops the pick: every value is judged on both seeds.

    python3 scripts/worst-case-pick.py results/worst-case-methods/tune [--values]

prints a table (or, with --values, `algo value` lines for the eval phase).
"""
import csv
import sys
from pathlib import Path

TASKS = ("Hopper-v4", "Goal_Point")
SEEDS = 2


def fail(message):
    print(f"error: {message}", file=sys.stderr)
    sys.exit(2)


def cells(path):
    """{value: mean} of one tuning sweep's cells.csv."""
    if not path.is_file():
        fail(f"{path} is missing: run `bash scripts/worst-case-methods.sh tune` first")
    out = {}
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            _, _, value = row["cell"].partition("=")
            if int(row["seeds"]) != SEEDS or int(row["incomplete"]) != 0 or row["mean"] == "":
                fail(f"{path}: {row['cell']} has {row['seeds']} finished seed(s) of {SEEDS}")
            out[value] = float(row["mean"])
    return out


def pick(tune, algo):
    means = {task: cells(tune / task / algo / "cells.csv") for task in TASKS}
    values = sorted(means[TASKS[0]], key=float)
    if sorted(means[TASKS[1]], key=float) != values:
        fail(f"{algo}: the two tasks' grids differ")
    ranks = {}
    for task in TASKS:
        order = sorted(values, key=lambda v: -means[task][v])
        ranks[task] = {v: order.index(v) + 1 for v in values}
    middle = values[len(values) // 2]
    key = lambda v: (sum(ranks[t][v] for t in TASKS), ranks["Goal_Point"][v], v != middle, float(v))
    return min(values, key=key), values, means, ranks


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    if len(args) != 1:
        fail("usage: worst-case-pick.py TUNE_FOLDER [--values]")
    tune = Path(args[0])
    algos = sorted({p.name for task in TASKS for p in (tune / task).glob("*") if p.is_dir()})
    if not algos:
        fail(f"{tune} holds no tuning sweep")
    for algo in algos:
        best, values, means, ranks = pick(tune, algo)
        if "--values" in sys.argv:
            print(algo, best)
            continue
        print(f"{algo}: picked {best}")
        for v in values:
            cols = "  ".join(f"{t} {means[t][v]:10.3f} (rank {ranks[t][v]})" for t in TASKS)
            print(f"  {v:>6}  {cols}{'  <-' if v == best else ''}")


if __name__ == "__main__":
    main()
