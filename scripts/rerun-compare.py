#!/usr/bin/env python3
"""Checks re-runs of committed runs made by a binary that counts every episode (an episode ended
by a simulator failure, "unstable", was left out of the return statistics before), and, with
--replace, puts their files in place of the committed ones.

    scripts/rerun-compare.py COMMITTED_ROOT RERUN_ROOT [--replace] [--max-report N]

Every run folder under RERUN_ROOT (a folder with a progress.csv) is paired with the folder at the
same relative path under COMMITTED_ROOT (scripts/rerun-unstable.sh writes OUT/<repo path>, so
`scripts/rerun-compare.py . OUT`). A re-run is finished when its progress.csv has as many rows
as the committed run's `epochs` (config.toml); an unfinished (or still running) one is listed as
pending and neither compared nor replaced. Runs are bit-reproducible, so for a finished re-run:

  (a) the rows are the same epochs, in the same order, under the same header;
  (b) every column other than the return columns and the wall-time columns is string-identical
      in every epoch (including eval_*: the committed runs have eval_every = 0);
  (c) the return columns (episodes, ep_ret_mean, ep_ret_min, ep_ret_max, ep_ret_std,
      ep_ret_cvar10, ep_ret_q10, ep_len_mean, success_rate, bound, confidence) differ only in
      epochs whose unstable_episodes > 0;
  (d) in every epoch the new episodes = old episodes + unstable_episodes;
  (e) with an episodes.csv: each epoch's train-phase records number `episodes`, of which
      `unstable_episodes` are flagged unstable, and their least return is ep_ret_min (relative
      tolerance 1e-9); no train record belongs to an epoch progress.csv lacks.

Any failure of these is a violation, printed with run, epoch, column and both values (the first
--max-report of each kind, default 200; 0 prints all). The summary gives, per run and in total,
the epochs with unstable episodes, the epochs whose return columns changed and the cells changed
per column. Exit status 1 on any violation (or a pairing problem), else 0.

--replace (only when there is no violation at all): for each finished re-run, its progress.csv
and episodes.csv are copied over the committed run's (temporary file + os.replace; config.toml is
left alone), and episodes.csv is added to the committed run's apo marker (.apo-run) when it has
one, since apo created the file. Run it again after more re-runs finish: a run whose committed
files are already the re-run's is counted as "already replaced" and left alone. A committed root
in an unpacked campaign (results/<name>/) is packed again after: bash scripts/results.sh pack <name>.
"""

import argparse
import collections
import csv
import filecmp
import math
import os
import re
import shutil
import sys

RETURN_COLS = [
    "episodes", "ep_ret_mean", "ep_ret_min", "ep_ret_max", "ep_ret_std", "ep_ret_cvar10",
    "ep_ret_q10", "ep_len_mean", "success_rate", "bound", "confidence",
]
TIME_COLS = ["steps_per_s", "time_s", "rollout_s", "update_pi_s", "update_v_s", "eval_s", "sim_s"]
PROGRESS, EPISODES, CONFIG, MARKER, LOCK = (
    "progress.csv", "episodes.csv", "config.toml", ".apo-run", "apo.lock")


def read_csv(path):
    with open(path, newline="") as f:
        reader = csv.reader(f)
        header = next(reader, None)
        rows = [r for r in reader if r]
    return header or [], rows


def config_epochs(path):
    """The top-level `epochs` of a config.toml, or None."""
    try:
        with open(path) as f:
            for line in f:
                s = line.strip()
                if s.startswith("["):
                    break
                m = re.match(r"epochs\s*=\s*(\d+)", s)
                if m:
                    return int(m.group(1))
    except OSError:
        pass
    return None


def locked(run):
    """Whether an apo process holds the run's lock (the run is being trained)."""
    path = os.path.join(run, LOCK)
    if not os.path.exists(path):
        return False
    try:
        import fcntl
    except ImportError:
        return False
    try:
        with open(path, "a") as f:
            try:
                fcntl.flock(f, fcntl.LOCK_SH | fcntl.LOCK_NB)
            except OSError:
                return True
            fcntl.flock(f, fcntl.LOCK_UN)
    except OSError:
        return False
    return False


def run_folders(root):
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if d != "checkpoints")
        if PROGRESS in filenames:
            yield dirpath


def as_int(s):
    try:
        return int(s)
    except ValueError:
        return 0


class Report:
    def __init__(self, max_report):
        self.max_report = max_report
        self.violations = collections.Counter()  # kind -> count
        self.lines = []

    def add(self, kind, text):
        self.violations[kind] += 1
        if self.max_report == 0 or self.violations[kind] <= self.max_report:
            self.lines.append(f"VIOLATION [{kind}] {text}")

    def total(self):
        return sum(self.violations.values())


def check_episodes(rel, path, prog_hdr, new_rows, rep):
    """(e): the rerun's episodes.csv against its progress.csv."""
    hdr, rows = read_csv(path)
    need = ["epoch", "phase", "return", "unstable"]
    missing = [c for c in need if c not in hdr]
    if missing:
        rep.add("episodes.csv", f"{rel}: {EPISODES} lacks the columns {missing} (header {hdr})")
        return
    ie, ip, ir, iu = (hdr.index(c) for c in need)
    count, unstable, worst = collections.Counter(), collections.Counter(), {}
    for n, r in enumerate(rows, start=2):
        if len(r) != len(hdr):
            rep.add("episodes.csv", f"{rel}: {EPISODES} line {n} has {len(r)} fields, not {len(hdr)}")
            continue
        if r[ip] != "train":
            continue
        try:
            e, ret = int(r[ie]), float(r[ir])
        except ValueError:
            rep.add("episodes.csv", f"{rel}: {EPISODES} line {n} does not parse: {r}")
            continue
        count[e] += 1
        unstable[e] += r[iu].strip().lower() in ("true", "1")
        worst[e] = ret if e not in worst else min(worst[e], ret)
    col = {c: prog_hdr.index(c) for c in ("epoch", "episodes", "ep_ret_min", "unstable_episodes")}
    seen = set()
    for r in new_rows:
        e = as_int(r[col["epoch"]])
        seen.add(e)
        eps = as_int(r[col["episodes"]])
        if count[e] != eps:
            rep.add("episodes.csv", f"{rel} epoch {e}: {count[e]} train episodes in {EPISODES}, "
                                    f"progress.csv episodes = {eps}")
        if unstable[e] != as_int(r[col["unstable_episodes"]]):
            rep.add("episodes.csv", f"{rel} epoch {e}: {unstable[e]} train episodes flagged unstable "
                                    f"in {EPISODES}, unstable_episodes = {r[col['unstable_episodes']]}")
        m = r[col["ep_ret_min"]]
        if count[e]:
            try:
                ok = math.isclose(worst[e], float(m), rel_tol=1e-9, abs_tol=0.0)
            except ValueError:
                ok = False
            if not ok:
                rep.add("episodes.csv", f"{rel} epoch {e}: min return in {EPISODES} = {worst[e]!r}, "
                                        f"ep_ret_min = {m!r}")
        elif m != "":
            rep.add("episodes.csv", f"{rel} epoch {e}: no train episode in {EPISODES}, ep_ret_min = {m!r}")
    extra = sorted(set(count) - seen)
    if extra:
        rep.add("episodes.csv", f"{rel}: {EPISODES} has train episodes of epochs {extra[:10]} "
                                f"that progress.csv does not have")


def compare_run(rel, old_dir, new_dir, rep, col_changes):
    """Compares one finished re-run; returns its per-run summary."""
    old_hdr, old_rows = read_csv(os.path.join(old_dir, PROGRESS))
    new_hdr, new_rows = read_csv(os.path.join(new_dir, PROGRESS))
    stats = {"epochs": len(new_rows), "unstable": 0, "changed": 0, "cells": 0,
             "v0": rep.total(), "episodes_csv": os.path.isfile(os.path.join(new_dir, EPISODES))}
    # (a) header and rows
    if old_hdr != new_hdr:
        only_old = [c for c in old_hdr if c not in new_hdr]
        only_new = [c for c in new_hdr if c not in old_hdr]
        rep.add("header", f"{rel}: the headers differ (only committed: {only_old}; only re-run: "
                          f"{only_new}; order differs: {not only_old and not only_new})")
    if "epoch" not in old_hdr or "epoch" not in new_hdr or "unstable_episodes" not in old_hdr:
        rep.add("header", f"{rel}: no epoch or unstable_episodes column")
        stats["violations"] = rep.total() - stats["v0"]
        return stats
    if len(old_rows) != len(new_rows):
        rep.add("rows", f"{rel}: {len(old_rows)} committed rows, {len(new_rows)} re-run rows")
    oi = {c: i for i, c in enumerate(old_hdr)}
    ni = {c: i for i, c in enumerate(new_hdr)}
    common = [c for c in old_hdr if c in ni]
    for n, (o, w) in enumerate(zip(old_rows, new_rows), start=1):
        if len(o) != len(old_hdr) or len(w) != len(new_hdr):
            rep.add("rows", f"{rel} row {n}: {len(o)} / {len(w)} fields, header {len(old_hdr)} / {len(new_hdr)}")
            continue
        epoch = o[oi["epoch"]]
        if w[ni["epoch"]] != epoch:
            rep.add("rows", f"{rel} row {n}: committed epoch {epoch}, re-run epoch {w[ni['epoch']]}")
            continue
        u = as_int(o[oi["unstable_episodes"]])
        stats["unstable"] += u > 0
        changed = False
        for c in common:
            a, b = o[oi[c]], w[ni[c]]
            if c in TIME_COLS or a == b:
                continue
            if c in RETURN_COLS:
                changed = True
                stats["cells"] += 1
                col_changes[c] += 1
                if u <= 0:
                    rep.add("return-column", f"{rel} epoch {epoch} {c}: committed {a!r}, re-run {b!r} "
                                             f"(unstable_episodes = {o[oi['unstable_episodes']]})")
            else:
                rep.add("other-column", f"{rel} epoch {epoch} {c}: committed {a!r}, re-run {b!r}")
        stats["changed"] += changed
        # (d)
        if "episodes" in oi and "episodes" in ni:
            want = as_int(o[oi["episodes"]]) + max(u, 0)
            if as_int(w[ni["episodes"]]) != want:
                rep.add("episodes", f"{rel} epoch {epoch}: re-run episodes {w[ni['episodes']]}, committed "
                                    f"{o[oi['episodes']]} + unstable {u} = {want}")
    # (e)
    if stats["episodes_csv"] and all(c in new_hdr for c in ("episodes", "ep_ret_min")):
        check_episodes(rel, os.path.join(new_dir, EPISODES), new_hdr, new_rows, rep)
    stats["violations"] = rep.total() - stats["v0"]
    return stats


def same_files(old_dir, new_dir):
    """Whether the committed run already holds the re-run's files (replaced before: the
    wall-time columns of two runs never agree otherwise)."""
    for name in (PROGRESS, EPISODES):
        new = os.path.join(new_dir, name)
        if name == EPISODES and not os.path.exists(new):
            continue
        old = os.path.join(old_dir, name)
        if not os.path.isfile(old) or not filecmp.cmp(old, new, shallow=False):
            return False
    return True


def atomic_copy(src, dst):
    tmp = os.path.join(os.path.dirname(dst), f".{os.path.basename(dst)}.rerun-tmp")
    shutil.copyfile(src, tmp)
    if os.path.exists(dst):
        shutil.copymode(dst, tmp)
    os.replace(tmp, dst)


def add_to_marker(run, name):
    path = os.path.join(run, MARKER)
    if not os.path.isfile(path):
        return False
    with open(path) as f:
        lines = f.read().splitlines()
    head = [l for l in lines if l.startswith("#")]
    names = [l for l in lines if l.strip() and not l.startswith("#")]
    if name in names:
        return False
    tmp = os.path.join(run, f".{MARKER}.rerun-tmp")
    with open(tmp, "w") as f:
        f.write("\n".join(head + sorted(names + [name])) + "\n")
    shutil.copymode(path, tmp)
    os.replace(tmp, path)
    return True


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("committed_root")
    ap.add_argument("rerun_root")
    ap.add_argument("--replace", action="store_true",
                    help="copy the re-runs' progress.csv and episodes.csv over the committed ones "
                         "(only when there is no violation)")
    ap.add_argument("--max-report", type=int, default=200, metavar="N",
                    help="violations printed per kind (0: all; default 200)")
    args = ap.parse_args()
    for d in (args.committed_root, args.rerun_root):
        if not os.path.isdir(d):
            sys.exit(f"error: {d} is not a directory")
    if os.path.realpath(args.committed_root) == os.path.realpath(args.rerun_root):
        sys.exit("error: COMMITTED_ROOT and RERUN_ROOT are the same folder")

    rep = Report(args.max_report)
    col_changes = collections.Counter()
    compared, pending, replaced_before = [], [], []
    for new_dir in run_folders(args.rerun_root):
        rel = os.path.relpath(new_dir, args.rerun_root)
        old_dir = os.path.join(args.committed_root, rel)
        if not os.path.isfile(os.path.join(old_dir, PROGRESS)):
            rep.add("pairing", f"{rel}: no committed run at {old_dir}")
            continue
        target = config_epochs(os.path.join(old_dir, CONFIG))
        if target is None:
            target = len(read_csv(os.path.join(old_dir, PROGRESS))[1])
        done = len(read_csv(os.path.join(new_dir, PROGRESS))[1])
        if done < target or locked(new_dir):
            pending.append((rel, done, target, locked(new_dir)))
            continue
        if same_files(old_dir, new_dir):
            replaced_before.append(rel)
            continue
        compared.append((rel, old_dir, new_dir, compare_run(rel, old_dir, new_dir, rep, col_changes)))

    for line in rep.lines:
        print(line)
    for kind, n in sorted(rep.violations.items()):
        if args.max_report and n > args.max_report:
            print(f"... {n - args.max_report} more [{kind}] violations not shown (--max-report 0 shows all)")

    # the summary
    if compared:
        w = max(len("run"), *(len(r[0]) for r in compared))
        print(f"\n{'run':<{w}}  epochs  unstable-epochs  changed-epochs  cells-changed  episodes.csv  violations")
        for rel, _, _, s in compared:
            v = s["violations"]
            print(f"{rel:<{w}}  {s['epochs']:>6}  {s['unstable']:>15}  {s['changed']:>14}  {s['cells']:>13}  "
                  f"{'yes' if s['episodes_csv'] else 'no':>12}  {v:>10}")
    tot = {k: sum(s[k] for *_, s in compared) for k in ("epochs", "unstable", "changed", "cells")}
    print(f"\nruns compared: {len(compared)} (with episodes.csv: "
          f"{sum(s['episodes_csv'] for *_, s in compared)}); pending: {len(pending)}")
    print(f"epochs: {tot['epochs']}; with unstable episodes: {tot['unstable']}; "
          f"whose return columns changed: {tot['changed']}; cells changed: {tot['cells']}")
    if col_changes:
        print("cells changed per column: " + ", ".join(f"{c} {col_changes[c]}" for c in RETURN_COLS if col_changes[c]))
    if replaced_before:
        print(f"already replaced (the committed run holds the re-run's files): {len(replaced_before)}")
    for rel, done, target, busy in pending:
        print(f"pending  {rel}  ({done}/{target} epochs{', running' if busy else ''})")
    if rep.total():
        print("violations: " + ", ".join(f"{k} {n}" for k, n in sorted(rep.violations.items())))
        print(f"FAIL: {rep.total()} violations" + ("; nothing replaced" if args.replace else ""))
        return 1
    print("OK: no violation")
    if args.replace:
        for rel, old_dir, new_dir, s in compared:
            atomic_copy(os.path.join(new_dir, PROGRESS), os.path.join(old_dir, PROGRESS))
            what = PROGRESS
            if s["episodes_csv"]:
                atomic_copy(os.path.join(new_dir, EPISODES), os.path.join(old_dir, EPISODES))
                what += " " + EPISODES
                if add_to_marker(old_dir, EPISODES):
                    what += f" (+{MARKER})"
            print(f"replaced {old_dir}: {what}")
        print(f"replaced {len(compared)} runs")
    return 0


if __name__ == "__main__":
    sys.exit(main())
