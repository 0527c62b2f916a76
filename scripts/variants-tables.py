#!/usr/bin/env python3
"""Returns tables of the variants' ablation (docs/results/variants.md), from the folder that
`scripts/variants-report.sh` writes (its `runs/`, named <env>-<algo>[-<cell>]-s<seed>).

Per environment and cell, over seeds (mean ± population std, as `apo report`): the mean, worst and CVaR 10 % return, each the
mean over the last N epochs of the run (progress.csv's ep_ret_mean, ep_ret_min, ep_ret_cvar10),
and P(the cell's worst return > the baseline's, TRPO unless BASELINE says) with its 95 %
stratified-bootstrap interval, from an
`apo report` of that environment's runs alone (written to REPORT/env/<env>). Then the statistics
over all environments from REPORT/report/statistics.json (TRPO-normalized scores): IQM and
P(cell > baseline) of the worst, CVaR 10 % and mean return.

    python3 scripts/variants-tables.py [REPORT] [ENV ...]   (default /tmp/variants-report)
APO (default ./target/release/apo) and LAST (default 10) as in variants-report.sh; BASELINE
(default trpo) is the algorithm every cell is compared with: for PAPO's side, BASELINE=ppo on a
report made with ALGOS="papo ppo trpo" (the statistics normalize by TRPO, so its runs stay in).
"""
import csv
import glob
import json
import os
import re
import statistics
import subprocess
import sys

report = sys.argv[1] if len(sys.argv) > 1 else "/tmp/variants-report"
apo = os.environ.get("APO", "./target/release/apo")
last = int(os.environ.get("LAST", "10"))
base = os.environ.get("BASELINE", "trpo")
runs_dir = os.path.join(report, "runs")
runs = sorted(glob.glob(os.path.join(runs_dir, "*-s[0-9]*")))
if not runs:
    sys.exit(f"error: no runs under {runs_dir}: run scripts/variants-report.sh first")

groups = {}  # env -> cell -> [run dirs]
for run in runs:
    stem = re.sub(r"-s[0-9]+$", "", os.path.basename(run))
    with open(os.path.join(run, "config.toml")) as f:
        env = next(line.split("=", 1)[1].strip().strip('"') for line in f if line.startswith("env "))
    cell = stem[len(env) + 1:]
    groups.setdefault(env, {}).setdefault(cell, []).append(run)
envs = sys.argv[2:] or sorted(groups)


def tail_means(run):
    """Mean over the last N epochs of (mean, worst, CVaR 10 %) return."""
    with open(os.path.join(run, "progress.csv")) as f:
        rows = list(csv.DictReader(f))[-last:]
    return [statistics.fmean(float(r[k]) for r in rows) for k in ("ep_ret_mean", "ep_ret_min", "ep_ret_cvar10")]


def stat(values):
    """mean ± standard deviation over the seeds (the population's, as `apo report` writes it)."""
    return f"{statistics.fmean(values):.2f} ± {statistics.pstdev(values):.2f}"


def versus_base(stats, metric):
    """Per label other than the baseline's: P(label > baseline) [lower, upper] of `metric`, and
    the IQMs."""
    analysis = next((m["analysis"] for m in stats if m["metric"] == metric), None)
    if not analysis:
        return {}, {}
    out = {}
    for p in analysis["probability_of_improvement"]:
        if p["y"] == base and p["x"] != base:
            out[p["x"]] = f"{p['point']:.2f} [{p['lower']:.2f}, {p['upper']:.2f}]"
    iqm = {k: f"{v['iqm']['point']:.3f} [{v['iqm']['lower']:.3f}, {v['iqm']['upper']:.3f}]"
           for k, v in analysis["aggregates"].items()}
    return out, iqm


print(f"| env | cell | seeds | mean return, last {last} | worst return, last {last} | "
      f"CVaR 10 %, last {last} | P(worst > {base}'s) [95 % CI] |")
print("|---|---|---|---|---|---|---|")
for env in envs:
    cells = groups.get(env, {})
    out = os.path.join(report, "env", env)
    env_runs = [r for c in cells.values() for r in c]
    done = subprocess.run([apo, "report", *env_runs, "--last", str(last), "--out", out],
                          capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"error: apo report of {env} failed:\n{done.stderr}")
    with open(os.path.join(out, "statistics.json")) as f:
        p_worst, _ = versus_base(json.load(f), "worst_last")
    for cell, cell_runs in sorted(cells.items(), key=lambda c: (c[0] in ("trpo", "ppo"), c[0])):
        values = [tail_means(r) for r in cell_runs]
        cols = [stat([v[i] for v in values]) for i in range(3)]
        algo, _, variant = cell.partition("-")
        label = f"{algo} ({variant})" if variant else algo  # as `apo report` labels the group
        p = p_worst.get(label, "" if label == base else "–")
        print(f"| {env} | {cell} | {len(cell_runs)} | " + " | ".join(cols) + f" | {p} |")

stats_path = os.path.join(report, "report", "statistics.json")
if os.path.exists(stats_path):
    with open(stats_path) as f:
        stats = json.load(f)
    print()
    print(f"| cell | metric, last N | P(cell > {base}) [95 % CI] | IQM cell | IQM {base} |")
    print("|---|---|---|---|---|")
    for metric in ("worst_last", "cvar10_last", "mean_last"):
        p, iqm = versus_base(stats, metric)
        for label in sorted(p):
            print(f"| {label} | {metric} | {p[label]} | {iqm.get(label, '–')} | {iqm.get(base, '–')} |")
