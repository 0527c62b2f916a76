#!/usr/bin/env python3
"""Runs the command blocks of the README and the handbook, so that a command shown in the docs
is a command that works.

Every fenced block whose info string starts with `sh` or `bash` in README.md, docs/*.md and
docs/results/*.md (docs/cli.md, the generated reference, aside) is either run here or marked
`long` in its info string (```sh long): a block that trains or benchmarks for minutes, or needs
what this check does not set up (root, a cluster, a GPU, the paper's checkout, a run made by a
long block). The blocks of one page run in order, in one scratch copy of the repository (its
files as git lists them), so a page's later block can use what an earlier one made; each runs
under `bash -e -o pipefail` with `apo` on PATH (APO, default target/debug/apo) and a scratch
HOME, and must end with status 0 within TIMEOUT seconds (default 300).

Every `rust` block is checked, not run: its lines must be, in order, lines of a doctest of a
crate's docs (`//!` or `///`, hidden `# ` lines aside) or of an example or test file, where
`cargo test` compiles and runs them.

    python3 scripts/doc_commands.py [PAGE...]        (default: every page)
    python3 scripts/doc_commands.py --list [PAGE...] (the blocks and whether each is run)

Exit status 1 when a block fails (its page, line, output tail and status are printed), 2 on
bad input, else 0."""
import glob
import os
import shutil
import subprocess
import sys
import tempfile
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def fail(message):
    """Bad input: the message on stderr, exit status 2."""
    print(f"error: {message}", file=sys.stderr)
    sys.exit(2)


def pages():
    found = ["README.md"] + sorted(glob.glob("docs/*.md")) + sorted(glob.glob("docs/results/*.md"))
    return [p for p in found if p != "docs/cli.md"]


def blocks(page, kinds=("sh", "bash")):
    """(line, info words, text) of each block of `page` whose info string starts with one of
    `kinds`."""
    found, inside, start, words, body = [], False, 0, [], []
    with open(os.path.join(REPO, page), encoding="utf-8") as f:
        for number, line in enumerate(f, 1):
            line = line.rstrip("\n")
            if line.startswith("```"):
                if inside:
                    if words[:1] and words[0] in kinds:
                        found.append((start, words, "\n".join(body) + "\n"))
                    inside = False
                else:
                    inside, start, words, body = True, number, line[3:].split(), []
            elif inside:
                body.append(line)
    if inside:
        fail(f"{page}:{start}: a code block is never closed")
    return found


def rust_sources():
    """The code of every doctest and example of the crates: lists of stripped lines."""
    found = []
    for path in sorted(glob.glob(os.path.join(REPO, "crates/*/src/**/*.rs"), recursive=True)):
        with open(path, encoding="utf-8") as f:
            lines = [l.strip() for l in f]
        docs = [l[3:].strip() for l in lines if l.startswith(("//!", "///"))]
        found.append([l for l in docs if l != "#" and not l.startswith("# ")])
    for pattern in ("crates/*/examples/*.rs", "crates/*/tests/**/*.rs", "tests/*/src/*.rs"):
        for path in sorted(glob.glob(os.path.join(REPO, pattern), recursive=True)):
            with open(path, encoding="utf-8") as f:
                found.append([l.strip() for l in f])
    return found


def quoted(block, sources):
    """Whether the non-empty lines of `block` appear, in order and adjacent (blank lines aside),
    in one of `sources`."""
    want = [l.strip() for l in block.splitlines() if l.strip()]
    for lines in sources:
        have = [l for l in lines if l]
        for start in range(len(have) - len(want) + 1):
            if have[start:start + len(want)] == want:
                return True
    return False


def unquoted_rust():
    """`page:line` of each rust block of the docs that no doctest, example or test holds."""
    sources, missing = rust_sources(), []
    for page in pages():
        for line, words, text in blocks(page, ("rust",)):
            if not quoted(text, sources):
                missing.append(f"{page}:{line}")
    return missing


def scratch_copy(dest):
    """The repository's files (tracked and new, as git lists them) copied into `dest`."""
    listed = subprocess.run(
        ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
        cwd=REPO, check=True, capture_output=True).stdout.split(b"\0")
    for rel in filter(None, listed):
        rel = rel.decode()
        src = os.path.join(REPO, rel)
        if not os.path.isfile(src):  # deleted in the work tree, not yet in git
            continue
        os.makedirs(os.path.join(dest, os.path.dirname(rel)), exist_ok=True)
        shutil.copy2(src, os.path.join(dest, rel), follow_symlinks=False)
    # what the scripts build or fetch is shared, never copied: the build and the caches
    for shared in ("target", ".cache"):
        if os.path.exists(os.path.join(REPO, shared)):
            os.symlink(os.path.join(REPO, shared), os.path.join(dest, shared))


def main():
    args = sys.argv[1:]
    listing = "--list" in args
    chosen = [a for a in args if a != "--list"]
    os.chdir(REPO)
    all_pages = pages()
    for page in chosen:
        if page not in all_pages:
            fail(f"{page} is not a page of the docs (README.md, docs/*.md, docs/results/*.md)")
    try:
        timeout = float(os.environ.get("TIMEOUT", "300"))
    except ValueError:
        timeout = -1
    if not timeout > 0:
        fail(f"TIMEOUT={os.environ.get('TIMEOUT')} is not a number of seconds above 0")
    apo = os.path.abspath(os.environ.get("APO", "target/debug/apo"))
    if not listing and not os.access(apo, os.X_OK):
        fail(f"{apo} is missing: cargo build -p apo-cli (or APO=path/to/apo)")
    ran, long_, failed, t0 = 0, 0, [], time.monotonic()
    for page in chosen or all_pages:
        found = blocks(page)
        runnable = [b for b in found if "long" not in b[1][1:]]
        long_ += len(found) - len(runnable)
        if listing:
            for line, words, text in found:
                first = text.strip().splitlines()[0] if text.strip() else ""
                print(f"{'long' if 'long' in words[1:] else 'run ':4}  {page}:{line}  {first[:90]}")
            continue
        if not runnable:
            continue
        with tempfile.TemporaryDirectory(prefix="apo-doc-") as tmp:
            work, home, bin_ = (os.path.join(tmp, d) for d in ("repo", "home", "bin"))
            os.makedirs(work)
            os.makedirs(home)
            os.makedirs(bin_)
            scratch_copy(work)
            os.symlink(apo, os.path.join(bin_, "apo"))
            env = dict(os.environ, HOME=home, APO=apo, PATH=bin_ + os.pathsep + os.environ["PATH"])
            for line, _, text in runnable:
                started = time.monotonic()
                try:
                    done = subprocess.run(["bash", "-e", "-o", "pipefail", "-c", text], cwd=work, env=env,
                                          stdin=subprocess.DEVNULL, capture_output=True, timeout=timeout)
                    status = done.returncode
                    output = (done.stdout + done.stderr).decode(errors="replace")
                except subprocess.TimeoutExpired as e:
                    status = f"timeout after {timeout:.0f} s"
                    output = ((e.stdout or b"") + (e.stderr or b"")).decode(errors="replace")
                took = time.monotonic() - started
                ran += 1
                print(f"{page}:{line}: {'ok' if status == 0 else 'FAILED'} in {took:.1f} s", flush=True)
                if status != 0:
                    tail = "\n".join(output.rstrip().splitlines()[-15:])
                    failed.append(f"{page}:{line}: status {status}\n{text}--- output (tail):\n{tail}\n")
    if listing:
        return 0
    for where in [] if chosen else unquoted_rust():
        failed.append(f"{where}: a rust block that no doctest, example or test holds (quote one)\n")
    print(f"ran {ran} command blocks in {time.monotonic() - t0:.0f} s; {long_} marked long, not run")
    if failed:
        print("\nfailed:\n" + "\n".join(failed), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
