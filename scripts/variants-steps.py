#!/usr/bin/env python3
"""Line-search figures of the variants' ablation (docs/results/variants.md): per cell, over
every finished run's epochs after the 5th (on a GUARD suite, TRPO is the GUARD campaign's
evaluation runs, results/guard-campaign/eval/<suite>/baselines), the share of full steps (accepted at try 0), the median
accepted try, the median KL of the step, and the rejected tries (KL / objective).

    python3 scripts/variants-steps.py [ABLATION]   (default results/variants/ablation)
"""
import glob
import os
import statistics
import sys

from apo_runs import finished_rows, need


root = sys.argv[1] if len(sys.argv) > 1 else "results/variants/ablation"
need(root, "results/guard-campaign")
print("| env | cell | epochs | full steps | median accepted try | median KL | rejected tries: KL / objective |")
print("|---|---|---|---|---|---|---|")
cells = [(*cell.split(os.sep)[-2:], os.path.join(cell, "*-s*")) for cell in sorted(glob.glob(os.path.join(root, "*", "*")))]
for suite in sorted({env for env, _, _ in cells if "_" in env}):
    cells.append((suite, "trpo (campaign)", f"results/guard-campaign/eval/{suite}/baselines/{suite}-trpo-s*"))
cells.sort(key=lambda c: c[0])
for env, name, runs in cells:
    rows = []
    for path in glob.glob(runs):
        run = finished_rows(path)
        if run is None:
            continue  # a run still going (or stopped early) is left out
        rows += [r for r in run if int(r["epoch"]) > 5]
    steps = [r for r in rows if r.get("line_search")]
    if not steps:
        continue
    tries = [int(r["line_search"].split(":")[1]) for r in steps if r["line_search"].startswith("accepted")]
    full = sum(1 for t in tries if t == 0)
    kls = [float(r["kl"]) for r in steps]
    rej_kl = sum(int(r["ls_rejected_kl"] or 0) for r in steps)
    rej_obj = sum(int(r["ls_rejected_objective"] or 0) for r in steps)
    print(f"| {env} | {name} | {len(steps)} | {100 * full / len(steps):.0f} % | "
          f"{statistics.median(tries) if tries else '–'} | {statistics.median(kls):.1e} | {rej_kl} / {rej_obj} |")
