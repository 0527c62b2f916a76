#!/usr/bin/env python3
"""Stages a running study's runs in git so that a fresh clone resumes them where they stopped.

A study's finished runs are committed as config.toml, progress.csv, episodes.csv and marker;
git ignores the checkpoints (results/.gitignore). A run still training when a session ends
would be lost on a new machine, since `apo sweep` cannot continue a run whose records have no
checkpoint. This script stages, for every run directory under the folders it is given:

- an unfinished run (its checkpoint is short of the config's `epochs`): its records, marker,
  config and the checkpoint folders `apo` resumes from (`checkpoints/latest`, and
  `checkpoints/previous` where a crash left it), forced past the ignore rule;
- a finished run: its records, marker and config, with any checkpoint it had staged before
  taken out of the index again (the files stay on disk);
- each sweep's `sweep.toml` and `cells.csv`.

A run that is training at that moment (its `apo.lock` is held) is paused (SIGSTOP to the pid
the lock names) while its files are staged and continued (SIGCONT) afterwards, so that what
is staged is what a crash at that instant would leave behind, which `apo` resumes from by
design (the checkpoint is written atomically, `previous` stands in for `latest` between
its two renames, the records are checked against the checkpoint on resume).

It stages only; commit afterwards:

    python3 scripts/study-snapshot.py results/paper-budget
    git commit -m "paper budget: in-progress runs"

and on the new machine run the study's script again (`bash scripts/paper-budget.sh`): its
sweeps skip the finished runs and resume the others from the committed checkpoints.
"""
from __future__ import annotations

import argparse
import fcntl
import json
import os
import signal
import subprocess
import sys
import tomllib
from pathlib import Path

RECORDS = ("config.toml", "progress.csv", "episodes.csv", ".apo-run")
SWEEP_FILES = ("sweep.toml", "cells.csv")
RESUME_FROM = ("latest", "previous")


def fail(message: str) -> None:
    print(f"error: {message}", file=sys.stderr)
    sys.exit(2)


def git(*args: str) -> None:
    subprocess.run(["git", *args], check=True)


def run_dirs(root: Path) -> list[Path]:
    """Run directories under `root`: folders with apo's marker and a config."""
    found = []
    for marker in sorted(root.rglob(".apo-run")):
        folder = marker.parent
        if marker.is_file() and not marker.is_symlink() and (folder / "config.toml").is_file():
            found.append(folder)
    return found


def checkpoint_epoch(run: Path) -> int | None:
    """The epoch of the checkpoint a resume would load (`latest`, else `previous`)."""
    for name in RESUME_FROM:
        state = run / "checkpoints" / name / "state.json"
        if state.is_file():
            try:
                return int(json.loads(state.read_text())["epoch"])
            except (ValueError, KeyError, TypeError) as e:
                fail(f"{state} cannot be read ({e}); the run's checkpoint is damaged")
    return None


def epochs_recorded(run: Path) -> int:
    """The epoch rows of the run's progress.csv (0 when there is none)."""
    progress = run / "progress.csv"
    if not progress.is_file():
        return 0
    with open(progress, "rb") as f:
        return max(sum(1 for line in f if line.strip()) - 1, 0)


def holder(run: Path) -> int | None:
    """The pid of the apo that holds the run's lock, or None when nobody does."""
    lock = run / "apo.lock"
    if not lock.is_file() or lock.is_symlink():
        return None
    with open(lock, "r+") as f:
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            text = f.read().split()
            if len(text) == 2 and text[0] == "pid" and text[1].isdigit():
                return int(text[1])
            fail(f"{lock} is held by a process that does not name itself ({' '.join(text)[:40]!r})")
        fcntl.flock(f, fcntl.LOCK_UN)
    return None


def stage(run: Path, target: int) -> str:
    epoch = checkpoint_epoch(run)
    records = [str(run / name) for name in RECORDS if (run / name).is_file()]
    # what was staged of the checkpoints before goes first: it may have rotated since
    git("rm", "-r", "-q", "-f", "--cached", "--ignore-unmatch", "--", str(run / "checkpoints"))
    if epoch is not None and epoch < target:
        folders = [str(run / "checkpoints" / n) for n in RESUME_FROM if (run / "checkpoints" / n).is_dir()]
        git("add", "-f", "--", *folders)
        git("add", "--", *records)
        return f"in progress, checkpoint at epoch {epoch} of {target}: staged with {', '.join(Path(f).name for f in folders)}"
    git("add", "--", *records)
    if epoch is not None:
        return f"finished ({epoch} of {target} epochs): records staged, no checkpoint"
    rows = epochs_recorded(run)
    if rows >= target:
        return f"finished ({rows} of {target} epochs, kept without checkpoints): records staged"
    return (f"warning: {rows} of {target} epochs recorded and no checkpoint: records staged, but "
            "the run cannot continue on another machine (apo sweep refuses it)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("folders", nargs="+", type=Path, help="a study's folder, e.g. results/paper-budget")
    args = parser.parse_args()
    for folder in args.folders:
        if not folder.is_dir() or folder.is_symlink():
            fail(f"{folder} is not a folder")
    for folder in args.folders:
        for sweep in sorted(folder.rglob("sweep.toml")):
            git("add", "--", *[str(sweep.parent / n) for n in SWEEP_FILES if (sweep.parent / n).is_file()])
        finished = 0
        for run in run_dirs(folder):
            with open(run / "config.toml", "rb") as f:
                try:
                    target = int(tomllib.load(f)["epochs"])
                except (tomllib.TOMLDecodeError, KeyError, ValueError) as e:
                    fail(f"{run / 'config.toml'} has no usable `epochs` ({e})")
            pid = holder(run)
            if pid is not None:
                os.kill(pid, signal.SIGSTOP)
            try:
                what = stage(run, target)
            finally:
                if pid is not None:
                    os.kill(pid, signal.SIGCONT)
            if what.startswith("finished"):
                finished += 1
                continue
            print(f"{run}: {what}{' (paused while staged: pid ' + str(pid) + ')' if pid else ''}")
        print(f"{folder}: {finished} finished run(s) staged as records")


if __name__ == "__main__":
    main()
