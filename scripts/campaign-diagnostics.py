#!/usr/bin/env python3
"""How each algorithm of the GUARD campaign steps (docs/results/guard-campaign.md): per suite and
algorithm, the proximal epoch's Adam steps (`pi_steps`), the step's KL (`kl`) and the policy's
entropy (`entropy`) of the runs' progress.csv, averaged over the last LAST epochs (default 20)
and then over seeds; only finished runs (last epoch = the epochs of the run's config.toml) count.
    python3 scripts/campaign-diagnostics.py [SUITE ...]   (default: every suite under
                                                          results/guard-campaign/eval)
CAMPAIGN and ROBUST name the campaign's and the robust column's folders, as in
scripts/campaign-report.sh."""
import glob
import os
import statistics
import sys

from apo_runs import finished_rows, need

campaign = os.environ.get("CAMPAIGN", "results/guard-campaign")
robust = os.environ.get("ROBUST", "results/variants/ablation")
need(campaign, robust)
last = int(os.environ.get("LAST", "20"))
columns = ["pi_steps", "kl", "entropy"]


def cells(suite):
    ev = f"{campaign}/eval/{suite}"
    return {
        "APO, paper": f"{ev}/apo/{suite}-apo-s[0-9]*",
        "APO, robust": f"{robust}/{suite}/robust/{suite}-apo-s[0-9]*",
        "PAPO, paper": f"{ev}/papo/{suite}-papo-s[0-9]*",
        "PAPO, robust": f"{robust}/{suite}/papo-robust/{suite}-papo-s[0-9]*",
        "TRPO": f"{ev}/baselines/{suite}-trpo-s[0-9]*",
        "PPO": f"{ev}/baselines/{suite}-ppo-s[0-9]*",
    }


def run_means(path):
    rows = finished_rows(path)
    if rows is None:
        return None
    means = {}
    for c in columns:
        values = [float(r[c]) for r in rows[-last:] if r.get(c) not in (None, "")]
        if values:
            means[c] = statistics.mean(values)
    return means


def main():
    suites = sys.argv[1:] or sorted(os.listdir(f"{campaign}/eval"))
    print(f"means over the last {last} epochs, then over the finished runs")
    print(f"| suite | algorithm | runs | {' | '.join(columns)} |")
    print("|---|---|---|" + "---|" * len(columns))
    for suite in suites:
        for name, pattern in cells(suite).items():
            runs = [m for m in map(run_means, sorted(glob.glob(pattern))) if m is not None]
            if not runs:
                continue
            cols = []
            for c in columns:
                values = [m[c] for m in runs if c in m]
                cols.append(f"{statistics.mean(values):.3g}" if values else "–")
            print(f"| {suite} | {name} | {len(runs)} | {' | '.join(cols)} |")


if __name__ == "__main__":
    main()
