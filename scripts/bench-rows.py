#!/usr/bin/env python3
"""Times the commands that read many rows at 1 M rows (and at 1/4 of that, to show how the
time grows): `apo stats` on a score file, `apo summary` and `apo report` on a run whose
`progress.csv` and `episodes.csv` hold that many rows. Prints wall time and peak memory
(max RSS) of each, as a Markdown table for docs/benchmarks.md.

    python3 scripts/bench-rows.py                  # target/release/apo, 1 M rows
    APO=path/to/apo python3 scripts/bench-rows.py --rows 1000000 --reps 100
"""
import argparse
import os
import random
import shutil
import subprocess
import tempfile
import time

ap = argparse.ArgumentParser()
ap.add_argument("--rows", type=int, default=1_000_000)
ap.add_argument("--reps", type=int, default=100, help="bootstrap resamples of apo stats/report")
args = ap.parse_args()
apo = os.environ.get("APO", "target/release/apo")


def timed(cmd):
    """Wall seconds and peak RSS in MiB of one command (which must succeed)."""
    with tempfile.TemporaryFile() as log:
        start = time.monotonic()
        child = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=log)
        _, status, usage = os.wait4(child.pid, 0)
        wall = time.monotonic() - start
        log.seek(0)
        err = log.read().decode(errors="replace")
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(cmd)} failed: {err[-2000:]}")
    return wall, usage.ru_maxrss / 1024


def scores(path, rows):
    """Two algorithms on 10 tasks, rows/20 runs each."""
    rng = random.Random(0)
    with open(path, "w") as f:
        f.write("algorithm,task,score\n")
        for i in range(rows):
            f.write(f"{'ab'[i % 2]},task{(i // 2) % 10},{rng.gauss(0.5, 0.2):.6f}\n")


def run(tmp, rows):
    """A real run of one epoch, its records then grown to `rows` epochs and `rows` episodes."""
    d = os.path.join(tmp, f"run{rows}")
    subprocess.run([apo, "train", "--algo", "ppo", "--env", "CartPole-v1", "--epochs", "1",
                    "--steps-per-epoch", "64", "--quiet", "--out", d], check=True,
                   stdout=subprocess.DEVNULL)
    with open(os.path.join(d, "progress.csv")) as f:
        header, first = f.read().splitlines()[:2]
    cells = first.split(",")
    columns = header.split(",")
    with open(os.path.join(d, "progress.csv"), "w") as f:
        f.write(header + "\n")
        for epoch in range(1, rows + 1):
            cells[columns.index("epoch")] = str(epoch)
            cells[columns.index("env_steps")] = str(64 * epoch)
            f.write(",".join(cells) + "\n")
    rng = random.Random(1)
    with open(os.path.join(d, "episodes.csv"), "w") as f:
        f.write("epoch,phase,env,seed,nth,return,length,unstable,success\n")
        for i in range(rows):
            f.write(f"{1 + i % rows},train,0,7,{i},{rng.uniform(5, 50):.3f},20,false,\n")
    return d


tmp = tempfile.mkdtemp(prefix="apo-bench-rows-")
try:
    print(f"| command | rows | wall s | max RSS MiB |\n|---|---:|---:|---:|")
    for rows in (args.rows // 4, args.rows):
        s = os.path.join(tmp, f"scores{rows}.csv")
        scores(s, rows)
        wall, rss = timed([apo, "stats", s, "--reps", str(args.reps)])
        print(f"| `apo stats --reps {args.reps}` | {rows} | {wall:.1f} | {rss:.0f} |")
        d = run(tmp, rows)
        wall, rss = timed([apo, "summary", d])
        print(f"| `apo summary` | {rows} | {wall:.1f} | {rss:.0f} |")
        wall, rss = timed([apo, "report", d, "--reps", str(args.reps)])
        print(f"| `apo report --reps {args.reps}` | {rows} | {wall:.1f} | {rss:.0f} |", flush=True)
finally:
    shutil.rmtree(tmp)
