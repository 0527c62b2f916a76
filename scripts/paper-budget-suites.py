#!/usr/bin/env python3
"""Picks the two GUARD suites that get paper-budget runs, by a rule fixed before any such run.

The rule (written before any paper-budget run):

    Among the 8 GUARD campaign suites (results/guard-campaign/eval/<suite>/baselines, whose TRPO
    runs are the folders <suite>-trpo-s<seed>), pick the two where TRPO's worst return still
    rises most over the last 20 epochs of its 1 M-step runs (100 epochs x 10 000 steps). For
    each seed take ep_ret_min per epoch; the rise is the least-squares slope of ep_ret_min
    against epoch over epochs 81-100, times 20 (the rise over the window), divided by the spread
    of TRPO's worst return on that suite: the standard deviation over seeds of the mean
    ep_ret_min over epochs 81-100 (if zero, the absolute value of its mean over seeds), so that
    suites of different scales compare. Average the normalized rise over the 5 seeds. Rank the
    suites by it, highest first; the first two are picked.

The standard deviation is the population one (the repository's convention, as in a sweep's
cells.csv); with 5 seeds on every suite the ranking does not depend on that choice.

    scripts/paper-budget-suites.py [--root results/guard-campaign/eval]

Prints the 8 suites ranked with their numbers (the normalized rise, its spread over seeds, the
raw rise per seed, the mean worst return over the window and its spread, and the TRPO epochs of
the window with unstable episodes, which the statistics count with the return they had reached)
and the two picked.
Exits non-zero when the runs are not what the rule expects (8 suites, 5 TRPO seeds each, 1 M
steps, epochs 81-100 present with a worst return).
"""

import argparse
import csv
import glob
import math
import os
import re
import statistics
import sys

from apo_runs import need

FIRST, LAST = 81, 100  # the window: the last 20 epochs of the 100-epoch runs
EPOCHS, STEPS = 100, 1_000_000
SUITES, SEEDS, PICK = 8, 5, 2


def slope(xs, ys):
    """The least-squares slope of ys against xs."""
    xm, ym = statistics.fmean(xs), statistics.fmean(ys)
    sxx = sum((x - xm) ** 2 for x in xs)
    return sum((x - xm) * (y - ym) for x, y in zip(xs, ys)) / sxx


def seed_of(run):
    m = re.search(r"-trpo-s(\d+)$", run)
    return int(m.group(1)) if m else None


def read_run(path, problems):
    """(epochs, worst returns, unstable epochs) of the window for one TRPO run."""
    with open(os.path.join(path, "progress.csv"), newline="") as f:
        rows = list(csv.DictReader(f))
    by_epoch = {int(r["epoch"]): r for r in rows}
    last = by_epoch.get(EPOCHS)
    if len(rows) != EPOCHS or last is None or int(last["env_steps"]) != STEPS:
        problems.append(f"{path}: not a finished 1 M-step run ({len(rows)} epochs, "
                        f"{last and last['env_steps']} steps at epoch {EPOCHS})")
    xs, ys, unstable = [], [], 0
    for e in range(FIRST, LAST + 1):
        r = by_epoch.get(e)
        if r is None or r["ep_ret_min"] == "":
            problems.append(f"{path}: epoch {e} has no ep_ret_min")
            continue
        xs.append(e)
        ys.append(float(r["ep_ret_min"]))
        unstable += int(r.get("unstable_episodes") or 0) > 0
    return xs, ys, unstable


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--root", default="results/guard-campaign/eval",
                    help="the campaign's evaluation folder (default: %(default)s, from the repository's root)")
    args = ap.parse_args()
    need(args.root)
    root = args.root
    if not os.path.isabs(root) and not os.path.isdir(root):
        root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", root)
    problems, table = [], []
    suites = sorted(d for d in os.listdir(root) if os.path.isdir(os.path.join(root, d, "baselines")))
    if len(suites) != SUITES:
        problems.append(f"{root}: {len(suites)} suites with baselines, not {SUITES}: {suites}")
    for suite in suites:
        runs = sorted(glob.glob(os.path.join(root, suite, "baselines", f"{suite}-trpo-s*")), key=seed_of)
        runs = [r for r in runs if seed_of(r) is not None and os.path.isfile(os.path.join(r, "progress.csv"))]
        if len(runs) != SEEDS:
            problems.append(f"{suite}: {len(runs)} TRPO runs, not {SEEDS}")
        if not runs:
            continue
        rises, means, unstable = [], [], 0
        for run in runs:
            xs, ys, u = read_run(run, problems)
            if len(xs) < 2:
                continue
            rises.append(slope(xs, ys) * (LAST - FIRST + 1))
            means.append(statistics.fmean(ys))
            unstable += u
        if not means:
            continue
        spread = statistics.pstdev(means) if len(means) > 1 else 0.0
        scale = spread if spread > 0 else abs(statistics.fmean(means))
        norm = [r / scale for r in rises] if scale > 0 else [math.nan] * len(rises)
        table.append({
            "suite": suite, "seeds": len(rises), "score": statistics.fmean(norm),
            "score_sd": statistics.pstdev(norm) if len(norm) > 1 else 0.0,
            "rises": rises, "worst": statistics.fmean(means), "spread": spread,
            "scale_is_mean": spread <= 0, "unstable": unstable,
        })
    table.sort(key=lambda t: (-t["score"] if not math.isnan(t["score"]) else math.inf, t["suite"]))

    print(f"TRPO's worst return (ep_ret_min) over epochs {FIRST}-{LAST} of the campaign's 1 M-step runs ({root}):")
    print("rise = least-squares slope x 20; normalized by the spread over seeds of the window's mean worst return\n")
    hdr = (f"{'rank':>4}  {'suite':<13} {'norm. rise':>10} {'± sd':>6}  {'mean worst':>10} {'spread':>8}  "
           f"{'rise per seed (raw)':<44} {'unst.ep':>7}")
    print(hdr)
    print("-" * len(hdr))
    for i, t in enumerate(table, start=1):
        rises = " ".join(f"{r:+8.3f}" for r in t["rises"])
        spread = f"{t['spread']:8.3f}" + ("*" if t["scale_is_mean"] else "")
        mark = "  <- picked" if i <= PICK else ""
        print(f"{i:>4}  {t['suite']:<13} {t['score']:+10.3f} {t['score_sd']:6.3f}  {t['worst']:+10.3f} {spread}  "
              f"{rises:<44} {t['unstable']:>7}{mark}")
    print("\nunst.ep: TRPO epochs of the window (over all seeds) with unstable episodes "
          "(counted in every statistic with the return they had reached)")
    if any(t["scale_is_mean"] for t in table):
        print("*: zero spread, normalized by the absolute mean instead")
    picked = [t["suite"] for t in table[:PICK]]
    print(f"picked: {', '.join(picked)}")
    if problems:
        print("\nproblems (the rule expects 8 suites x 5 finished 1 M-step TRPO runs):", file=sys.stderr)
        for p in problems:
            print(f"  {p}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
