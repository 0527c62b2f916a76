#!/usr/bin/env python3
"""Checks `apo stats` against rliable, the reference implementation of Agarwal et al.,
"Deep Reinforcement Learning at the Edge of the Statistical Precipice" (NeurIPS 2021).

    python3 scripts/check_rliable.py [--apo target/release/apo] [--reps 5000]
    python3 scripts/check_rliable.py --self-test      # rliable only, no apo binary needed

What it does:

1. Makes a virtual environment (default `.cache/rliable-venv`, git-ignored and reused by
   later runs; `--temp-venv` uses a throwaway one in a temporary directory instead) and
   installs the pinned versions in PINS there, then runs itself again with that
   environment's python. The host side needs only the standard library.
2. Builds fixed score matrices (numpy seeds are fixed): `mixed` (3 algorithms x 8 tasks x 5
   runs from a normal with a per-run offset shared by all tasks, a log-normal and a bimodal
   distribution), `ties` (scores on a 0.5 grid, many ties, taus on the same grid to
   exercise the strict `score > tau`), `unequal_runs` (3 runs against 10 runs), and
   `identical` (an algorithm equal to another on two tasks, rliable's 0.5 rule, and equal
   up to the order of runs on a third).
3. Writes each as a CSV (`algorithm,task,score`), runs
   `apo stats CSV --reps R --ci-seed S --json --taus LO:HI:N` and compares every number
   with rliable's (`rliable.metrics` for the point estimates, rliable's stratified
   bootstraps with arch's percentile intervals for the confidence intervals, and
   `rliable.library.score_distributions` as `create_performance_profile` uses it).

Comparison rules (printed with the table):

* Point estimates (mean, median, IQM, optimality gap, probability of improvement, profile
  fractions) and the taus (against numpy.linspace): |apo - rliable| <= 1e-12.
* Interval endpoints. The two sides draw different resamples (different generators), so
  endpoints agree only up to Monte-Carlo noise; the rule bounds that noise exactly instead
  of estimating it. Through the bootstrap distribution F, the i-th smallest of n
  resampled statistics sits at a uniform order statistic, Beta(i, n + 1 - i), whatever F
  is (continuous, or a lattice as for profiles and the probability of improvement). A
  percentile endpoint from R resamples (numpy's default linear interpolation, as arch
  uses) lies between the order statistics j and j + 1, j = floor((R - 1) p) + 1,
  p = 0.025 or 0.975, so its place in F is inside [a, b] = [Beta(j, R + 1 - j) quantile
  alpha, Beta(j + 1, R - j) quantile 1 - alpha] but with probability 2 alpha. The
  reference is rliable's own bootstrap with M resamples (M = 4 R for aggregates and
  profiles, --ref-factor; M = R for the probability of improvement, --poi-ref-factor,
  scipy's mannwhitneyu making that bootstrap slow): apo's endpoint must lie between
  the reference's order statistics that fall below a, and above b, but with probability
  alpha each (1e-9 slack); where no order statistic does (too few resamples, e.g.
  R = M = 1000 for the lower edge of a lower end), that side of the band stays open. alpha is the one-sided normal tail at k = --sigmas (default 4:
  alpha = 3.2e-5), so a correct implementation fails an endpoint with probability at most
  4 alpha (a union bound; really far less: each edge of the band lies about 5.4 (M = 4 R)
  to 5.7 (M = R) standard deviations of the difference from where apo's endpoint falls
  on average). For R = 5000 the band runs from rliable's 1.35 % to 4.0 %
  quantile for a lower end (M = 20000), 1.0 % to 4.6 % for the probability of improvement
  (M = 5000). The table's `rliable` is rliable's 95 % endpoint from the M resamples and
  `tol` the distance from it to the band's edge on apo's side. Wrong resampling (whole
  runs instead of each task's runs: the `mixed` case's per-run offsets shared across
  tasks expose it) or wrong coverage (90 % instead of 95 %) fail on the order of a
  hundred rows. `--self-test` puts rliable's public `get_interval_estimates` /
  `create_performance_profile` with R resamples (other seeds) in apo's place.
* The reference interval of P(y > x) is rliable's bootstrap of P(x > y) mirrored:
  P(Y > X) = 1 - P(X > Y) holds on every resample (ties count one half both ways), so the
  percentile interval mirrors too. This halves the time in mannwhitneyu; the point
  estimates of both orders come from rliable directly, and the self-test's candidate
  (rliable's get_interval_estimates on the pair (y, x)) checks the mirror.

Time: the first run installs the environment (about 35 s); then a
check with R = 5000 takes about 3.5 minutes of two busy cores (rliable's bootstraps; apo
itself takes seconds), and the self-test about the same. `--reps 1000` runs in about 40 s.

Exits 1 when anything fails (or apo cannot be run), 2 on a setup error.
"""

import argparse
import contextlib
import csv
import json
import math
import os
import subprocess
import sys
import tempfile
import time
import zlib
from pathlib import Path

# The versions the check was written against. pandas < 3: arch 7.2 fails to import with
# pandas 3 (its `deprecate_kwarg` signature changed).
PINS = [
    "rliable==1.2.0",
    "arch==7.2.0",
    "numpy==2.4.6",
    "scipy==1.17.1",
    "pandas==2.3.3",
]
PINS_FILE = "check_rliable-pins.txt"
ROOT = Path(__file__).resolve().parent.parent
CONFIDENCE = 0.95
POINT_TOL = 1e-12
SLACK = 1e-9
CI_SEED = 7  # apo's --ci-seed
REF_SEED = 20211206  # base of the numpy seeds of rliable's bootstraps


def parse_args(argv):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--apo", default="target/release/apo", help="apo binary (default: %(default)s)")
    parser.add_argument("--self-test", action="store_true",
                        help="no apo: compare rliable's own R-resample intervals with the reference")
    parser.add_argument("--reps", type=int, default=5000, help="bootstrap resamples R (default: %(default)s)")
    parser.add_argument("--ref-factor", type=int, default=4,
                        help="rliable's reference bootstraps of the aggregates and profiles draw "
                             "ref_factor x R resamples (default: %(default)s)")
    parser.add_argument("--poi-ref-factor", type=int, default=1,
                        help="the same for the probability of improvement, whose bootstrap is slow "
                             "(default: %(default)s)")
    parser.add_argument("--sigmas", type=float, default=4.0,
                        help="k of the interval rule (see the docstring; default: %(default)s)")
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1,
                        help="parallel processes for rliable's bootstraps (default: %(default)s)")
    parser.add_argument("--failures-only", action="store_true", help="print only the failing rows")
    parser.add_argument("--venv", default=str(ROOT / ".cache" / "rliable-venv"),
                        help="virtual environment to make or reuse (default: %(default)s)")
    parser.add_argument("--temp-venv", action="store_true",
                        help="install into a throwaway environment in a temporary directory")
    parser.add_argument("--keep", metavar="DIR", help="write the score CSVs and apo's JSON under DIR")
    parser.add_argument("--in-venv", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if min(args.reps, args.ref_factor, args.poi_ref_factor, args.jobs) < 1:
        parser.error("--reps, --ref-factor, --poi-ref-factor and --jobs must be positive")
    return args


# ----------------------------------------------------------------------------------------
# Host side: standard library only.


def ensure_venv(venv: Path) -> Path:
    """Makes `venv` with PINS installed unless it already has them; returns its python."""
    python = venv / "bin" / "python"
    pins_file = venv / PINS_FILE
    wanted = "\n".join(PINS) + "\n"
    if python.exists() and pins_file.exists() and pins_file.read_text() == wanted:
        print(f"using {venv} ({', '.join(PINS)})", flush=True)
        return python
    start = time.monotonic()
    if not python.exists():
        print(f"creating a virtual environment in {venv}", flush=True)
        subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    print(f"pip install {' '.join(PINS)}", flush=True)
    subprocess.run([str(python), "-m", "pip", "install", "--quiet", "--disable-pip-version-check", *PINS],
                   check=True)
    pins_file.write_text(wanted)
    print(f"environment ready in {time.monotonic() - start:.1f} s", flush=True)
    return python


def host_main(args, argv) -> int:
    temp = tempfile.TemporaryDirectory(prefix="rliable-venv-") if args.temp_venv else contextlib.nullcontext()
    with temp as temp_dir:
        venv = Path(temp_dir) / "venv" if args.temp_venv else Path(args.venv)
        try:
            python = ensure_venv(venv)
        except (subprocess.CalledProcessError, OSError) as e:
            print(f"check_rliable: could not set up {venv}: {e}", file=sys.stderr)
            return 2
        return subprocess.run([str(python), str(Path(__file__).resolve()), *argv, "--in-venv"]).returncode


# ----------------------------------------------------------------------------------------
# Venv side: numpy and rliable.


def make_cases(np):
    """The score matrices: name -> (taus as (LO, HI, N), {algorithm: runs x tasks array})."""
    cases = {}

    rng = np.random.default_rng(1)
    tasks, runs = 8, 5
    level = rng.uniform(0.3, 1.5, size=tasks)
    run_offset = rng.normal(0.0, 0.25, size=(runs, 1))  # shared by the tasks of a run
    normal = level + run_offset + rng.normal(0.0, 0.2, size=(runs, tasks))
    lognormal = np.exp(rng.normal(np.log(level), 0.5, size=(runs, tasks)))
    low = rng.random((runs, tasks)) < 0.4
    bimodal = np.where(low, rng.uniform(0.0, 0.1, (runs, tasks)), rng.normal(1.2, 0.2, (runs, tasks)))
    cases["mixed"] = ((0.0, 2.0, 21), {"normal": normal, "lognormal": lognormal, "bimodal": bimodal})

    rng = np.random.default_rng(2)
    grid_a = rng.integers(0, 5, size=(6, 6)) * 0.5
    grid_b = rng.integers(1, 5, size=(6, 6)) * 0.5
    cases["ties"] = ((0.0, 2.0, 9), {"grid_a": grid_a, "grid_b": grid_b})

    rng = np.random.default_rng(3)
    few = rng.normal(1.0, 0.6, size=(3, 5))
    many = rng.normal(0.8, 0.4, size=(10, 5))
    cases["unequal_runs"] = ((-1.0, 3.0, 17), {"few": few, "many": many})

    rng = np.random.default_rng(4)
    base = rng.uniform(0.0, 2.0, size=(5, 4))
    copy = base.copy()
    copy[:, 1] = rng.uniform(0.0, 2.0, size=5)  # different
    copy[:, 3] = base[::-1, 3]  # same runs, other order: not array_equal, still 0.5
    cases["identical"] = ((0.0, 2.0, 11), {"base": base, "copy": copy})  # tasks 0, 2 equal
    return cases


def task_names(scores):
    return [f"task{t}" for t in range(scores.shape[1])]


def write_csv(path: Path, algorithms):
    """One row per run; an algorithm's rows go run by run, each run over all tasks."""
    with open(path, "w", newline="") as f:
        out = csv.writer(f)
        out.writerow(["algorithm", "task", "score"])
        for name, scores in algorithms.items():
            names = task_names(scores)
            for run in scores:
                for task, score in zip(names, run):
                    out.writerow([name, task, repr(float(score))])


def seed_of(*parts) -> int:
    return (REF_SEED + zlib.crc32("/".join(map(str, parts)).encode())) % 2**32


def aggregates(scores):
    """The four aggregates, rliable's functions (gamma 1 for the optimality gap)."""
    import numpy as np
    from rliable import metrics

    return np.array([
        metrics.aggregate_mean(scores),
        metrics.aggregate_median(scores),
        metrics.aggregate_iqm(scores),
        metrics.aggregate_optimality_gap(scores),
    ])


AGGREGATES = ["mean", "median", "iqm", "optimality_gap"]


class ProfileFunction:
    """What create_performance_profile bootstraps (use_score_distribution=True)."""

    def __init__(self, taus):
        self.taus = taus

    def __call__(self, scores):
        from rliable import library

        return library.score_distributions(scores, self.taus)


def band_levels(p, reps, ref_reps, alpha):
    """Quantile levels (low, high) of a bootstrap of `ref_reps` resamples between which a
    correct percentile endpoint at `p` from `reps` other resamples lies, but with
    probability at most 4 `alpha`, whatever the bootstrap distribution F.

    Through F, the i-th smallest of n draws sits at a uniform order statistic,
    Beta(i, n + 1 - i). A type-7 endpoint interpolates the order statistics j and j + 1,
    j = floor((R - 1) p) + 1, so it sits in [a, b] = [Beta(j, R + 1 - j) quantile alpha,
    Beta(j + 1, R - j) quantile 1 - alpha] but with probability 2 alpha. The band ends at
    the reference's order statistics that lie below a, and above b, but with probability
    alpha each."""
    from scipy.stats import beta

    j = math.floor((reps - 1) * p) + 1
    a = beta.ppf(alpha, j, reps + 1 - j)
    b = beta.ppf(1.0 - alpha, j + 1, reps - j) if j < reps else 1.0
    m = ref_reps

    def search(good, lo, hi):  # the first i in [lo, hi) with good(i), hi if none
        while lo < hi:
            mid = (lo + hi) // 2
            if good(mid):
                hi = mid
            else:
                lo = mid + 1
        return lo

    # The largest i with P(U_(i) > a) <= alpha; none (no lower limit) if even the minimum
    # fails that, as with few resamples.
    low = search(lambda i: beta.ppf(1.0 - alpha, i, m + 1 - i) > a, 1, m + 1) - 1
    # The smallest i with P(U_(i) < b) <= alpha; none (no upper limit) if even the maximum
    # fails.
    high = search(lambda i: beta.ppf(alpha, i, m + 1 - i) >= b, 1, m + 1)
    level = lambda i: (i - 1) / (m - 1) if m > 1 else 0.5  # type 7: U_(i) is at that level
    return (level(low) if low >= 1 else None), (level(high) if high <= m else None)


def quantile_at(bootstrap, func, reps, level):
    """The bootstrap's percentile at `level`, through arch's conf_int (reusing its draws)."""
    if level <= 0.5:
        size, row = 1.0 - 2.0 * level, 0
    else:
        size, row = 1.0 - 2.0 * (1.0 - level), 1
    size = min(max(size, 1e-15), 1.0 - 1e-15)  # conf_int wants 0 < size < 1
    return bootstrap.conf_int(func, reps=reps, method="percentile", size=size, reuse=True)[row]


def reference_job(job):
    """rliable's bootstrap with M resamples: its 95 % endpoints and, for each, its values
    at the levels of the band (see band_levels). Runs in a worker process."""
    import numpy as np
    from rliable import library, metrics

    kind, data, reps, seed, levels, taus = job
    if kind == "aggregates":
        bootstrap, func = library.StratifiedBootstrap(data), aggregates
    elif kind == "improvement":
        bootstrap, func = library.StratifiedIndependentBootstrap(*data), metrics.probability_of_improvement
    else:
        bootstrap, func = library.StratifiedBootstrap(data), ProfileFunction(taus)
    np.random.seed(seed)  # rliable resamples with the global np.random
    ci = bootstrap.conf_int(func, reps=reps, method="percentile", size=CONFIDENCE)

    def at(level, unbounded):  # no level: that side of the band is open
        return np.full_like(ci[0], unbounded) if level is None else quantile_at(bootstrap, func, reps, level)

    return {
        "lower": ci[0], "upper": ci[1],
        "lower_band": (at(levels["lower"][0], -math.inf), at(levels["lower"][1], math.inf)),
        "upper_band": (at(levels["upper"][0], -math.inf), at(levels["upper"][1], math.inf)),
    }


def candidate_job(job):
    """Self-test: rliable's public functions with R resamples, standing in for apo."""
    import numpy as np
    from rliable import library, metrics

    kind, data, reps, seed, taus = job
    np.random.seed(seed)
    if kind == "aggregates":
        points, cis = library.get_interval_estimates(
            {"a": data}, aggregates, method="percentile", reps=reps, confidence_interval_size=CONFIDENCE)
    elif kind == "improvement":
        points, cis = library.get_interval_estimates(
            {"a": tuple(data)}, metrics.probability_of_improvement, method="percentile", reps=reps,
            confidence_interval_size=CONFIDENCE)
    else:
        points, cis = library.create_performance_profile(
            {"a": data}, taus, method="percentile", reps=reps, confidence_interval_size=CONFIDENCE)
    return np.atleast_1d(points["a"]), cis["a"][0], cis["a"][1]


class Table:
    def __init__(self, failures_only):
        self.rows = []
        self.failures_only = failures_only

    def add(self, case, subject, quantity, got, want, tol, ok=None):
        diff = abs(got - want) if got is not None and want is not None else math.inf
        if ok is None:
            ok = diff <= tol
        self.rows.append((case, subject, quantity, got, want, diff, tol, bool(ok)))

    def point(self, case, subject, quantity, got, want):
        self.add(case, subject, quantity, got, want, POINT_TOL)

    def endpoint(self, case, subject, quantity, got, want, band):
        """`band` = (rliable's quantile at p - k s, at p + k s)."""
        low, high = band
        if got is None:
            self.add(case, subject, quantity, None, want, math.nan, False)
            return
        tol = (high - want if got >= want else want - low) + SLACK
        self.add(case, subject, quantity, got, want, tol, low - SLACK <= got <= high + SLACK)

    def fail(self, case, subject, quantity, why):
        self.rows.append((case, subject, quantity, why, None, math.inf, math.nan, False))

    def print(self):
        def fmt(v):
            if v is None:
                return "-"
            return v if isinstance(v, str) else f"{v:.15g}"

        header = ("case", "subject", "quantity", "candidate", "rliable", "|diff|", "tol", "ok")
        lines = [header] + [
            (c, s, q, fmt(g), fmt(w), f"{d:.2e}", f"{t:.2e}", "ok" if ok else "FAIL")
            for c, s, q, g, w, d, t, ok in self.rows
            if not self.failures_only or not ok
        ]
        widths = [max(len(str(line[i])) for line in lines) for i in range(len(header))]
        for line in lines:
            print("  ".join(str(v).ljust(w) for v, w in zip(line, widths)).rstrip())
        failed = sum(not r[7] for r in self.rows)
        return failed


def run_apo(apo, csv_path, taus, reps, keep):
    lo, hi, n = taus
    command = [apo, "stats", str(csv_path), "--reps", str(reps), "--ci-seed", str(CI_SEED), "--json",
               f"--taus={lo!r}:{hi!r}:{n}"]  # `=`: LO may start with a minus
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} exited {done.returncode}: {done.stderr.strip()}")
    if keep:
        csv_path.with_suffix(".json").write_text(done.stdout)
    return json.loads(done.stdout)


def apo_view(result):
    """apo's JSON as {aggregates: {algo: {name: (point, lower, upper)}}, improvement:
    {(x, y): (...)}, profiles: {algo: (fractions, lowers, uppers)}, taus}."""
    aggregates_ = {
        algo: {name: (e["point"], e["lower"], e["upper"]) for name, e in values.items()}
        for algo, values in result.get("aggregates", {}).items()
    }
    improvement = {(p["x"], p["y"]): (p["point"], p["lower"], p["upper"])
                   for p in result.get("probability_of_improvement", [])}
    profiles = dict(result.get("profiles", {}))
    taus = profiles.pop("taus", None)
    profiles = {algo: (p["fraction"], p["lower"], p["upper"]) for algo, p in profiles.items()}
    return {"aggregates": aggregates_, "improvement": improvement, "profiles": profiles, "taus": taus,
            "reps": result.get("reps"), "confidence": result.get("confidence"), "tasks": result.get("tasks")}


def venv_main(args) -> int:
    from multiprocessing import Pool

    import numpy as np
    import rliable
    from importlib.metadata import version
    from rliable import library, metrics

    reps, ref_reps, poi_ref_reps = args.reps, args.reps * args.ref_factor, args.reps * args.poi_ref_factor
    tail = (1.0 - CONFIDENCE) / 2.0

    alpha = 0.5 * math.erfc(args.sigmas / math.sqrt(2.0))  # the one-sided normal tail at k

    def levels_for(m):
        return {"lower": band_levels(tail, reps, m, alpha), "upper": band_levels(1.0 - tail, reps, m, alpha)}

    levels, poi_levels = levels_for(ref_reps), levels_for(poi_ref_reps)
    print(f"rliable {version('rliable')}, arch {version('arch')}, numpy {np.__version__}, "
          f"scipy {version('scipy')} ({Path(rliable.__file__).parent})")
    print(f"candidate: {'rliable get_interval_estimates / create_performance_profile (self-test)' if args.self_test else args.apo}")
    print(f"rules: points and taus: |diff| <= {POINT_TOL:g}. Interval endpoints (R = {reps} resamples): "
          f"within rliable's bootstrap quantiles at the levels of an exact order-statistic band "
          f"(false-alarm chance <= 4 x {alpha:.2g} per endpoint, k = {args.sigmas:g}), plus {SLACK:g}:")
    def show(level, unbounded):
        return unbounded if level is None else f"q({level:.5f})"

    for what, m, lv in (("aggregates, profiles", ref_reps, levels), ("probability of improvement", poi_ref_reps, poi_levels)):
        print(f"  {what}: M = {m}, lower end in [{show(lv['lower'][0], '-inf')}, {show(lv['lower'][1], 'inf')}], "
              f"upper end in [{show(lv['upper'][0], '-inf')}, {show(lv['upper'][1], 'inf')}]")
        if None in lv["lower"] + lv["upper"]:
            print("    (too few resamples to bound that side: raise --reps or the reference factors)")
    apo = Path(args.apo)
    if not apo.is_absolute() and not apo.exists():
        apo = ROOT / apo  # relative to the repository when not to the working directory
    if not args.self_test and not apo.exists():
        print(f"check_rliable: no apo binary at {args.apo} (build it, pass --apo, or use --self-test)",
              file=sys.stderr)
        return 2

    cases = make_cases(np)
    table = Table(args.failures_only)
    start = time.monotonic()

    # apo (or, in the self-test, rliable at R resamples) for every case.
    keep_dir = Path(args.keep) if args.keep else None
    if keep_dir:
        keep_dir.mkdir(parents=True, exist_ok=True)
    candidates = {}
    apo_seconds = 0.0
    with tempfile.TemporaryDirectory(prefix="check-rliable-") as temp:
        for name, (taus, algorithms) in cases.items():
            if args.self_test:
                continue
            path = (keep_dir or Path(temp)) / f"{name}.csv"
            write_csv(path, algorithms)
            t0 = time.monotonic()
            try:
                candidates[name] = apo_view(run_apo(str(apo), path, taus, reps, keep_dir))
            except (RuntimeError, json.JSONDecodeError, KeyError, TypeError) as e:
                table.fail(name, "-", "apo stats", str(e))
            apo_seconds += time.monotonic() - t0

    # rliable's reference bootstraps (and the self-test's candidates), in parallel.
    reference_jobs, candidate_jobs = [], []
    for name, (taus, algorithms) in cases.items():
        view = candidates.get(name)
        tau_values = np.linspace(*taus)
        if view and view["taus"] is not None and len(view["taus"]) == len(tau_values):
            tau_values = np.array(view["taus"], dtype=float)  # profile at apo's own taus
        names = list(algorithms)
        for algo in names:
            for kind in ("aggregates", "profile"):
                reference_jobs.append(((name, kind, algo),
                                       (kind, algorithms[algo], ref_reps, seed_of(name, kind, algo), levels, tau_values)))
                candidate_jobs.append(((name, kind, algo),
                                       (kind, algorithms[algo], reps, seed_of("candidate", name, kind, algo), tau_values)))
        for i, x in enumerate(names):
            for y in names[i + 1:]:
                pair = (algorithms[x], algorithms[y])
                reference_jobs.append(((name, "improvement", (x, y)),
                                       ("improvement", pair, poi_ref_reps, seed_of(name, x, y), poi_levels, None)))
                # The self-test's candidate takes the other order, so the mirror is checked too.
                candidate_jobs.append(((name, "improvement", (y, x)),
                                       ("improvement", pair[::-1], reps, seed_of("candidate", name, y, x), None)))
    # The probability-of-improvement bootstraps take longest: start them first.
    reference_jobs.sort(key=lambda item: item[0][1] != "improvement")
    candidate_jobs.sort(key=lambda item: item[0][1] != "improvement")
    t0 = time.monotonic()
    with Pool(min(args.jobs, len(reference_jobs))) as pool:
        reference_async = pool.map_async(reference_job, [job for _, job in reference_jobs], chunksize=1)
        candidate_async = (pool.map_async(candidate_job, [job for _, job in candidate_jobs], chunksize=1)
                           if args.self_test else None)
        reference = dict(zip((key for key, _ in reference_jobs), reference_async.get()))
        if candidate_async is not None:
            by_key = dict(zip((key for key, _ in candidate_jobs), candidate_async.get()))
    rliable_seconds = time.monotonic() - t0

    if args.self_test:
        # The candidate views, from rliable's public functions.
        for name, (taus, algorithms) in cases.items():
            view = {"aggregates": {}, "improvement": {}, "profiles": {}, "taus": list(np.linspace(*taus)),
                    "reps": reps, "confidence": CONFIDENCE, "tasks": task_names(next(iter(algorithms.values())))}
            for (case, kind, subject), (points, lowers, uppers) in by_key.items():
                if case != name:
                    continue
                if kind == "aggregates":
                    view["aggregates"][subject] = {
                        a: (points[i], lowers[i], uppers[i]) for i, a in enumerate(AGGREGATES)}
                elif kind == "improvement":
                    view["improvement"][subject] = (points[0], lowers[0], uppers[0])
                else:
                    view["profiles"][subject] = (list(points), list(lowers), list(uppers))
            candidates[name] = view
        # The reference calls the bootstrap classes directly; get_interval_estimates and
        # create_performance_profile must give the same numbers from the same seed.
        taus, algorithms = cases["mixed"]
        scores, other = algorithms["normal"], algorithms["bimodal"]
        tau_values = np.linspace(*taus)
        for kind, direct, through in [
            ("aggregates", lambda: library.StratifiedBootstrap(scores).conf_int(
                aggregates, reps=300, method="percentile", size=CONFIDENCE),
             lambda: library.get_interval_estimates({"a": scores}, aggregates, reps=300)[1]["a"]),
            ("improvement", lambda: library.StratifiedIndependentBootstrap(scores, other).conf_int(
                metrics.probability_of_improvement, reps=100, method="percentile", size=CONFIDENCE),
             lambda: library.get_interval_estimates({"a": (scores, other)}, metrics.probability_of_improvement,
                                                    reps=100)[1]["a"]),
            ("profile", lambda: library.StratifiedBootstrap(scores).conf_int(
                ProfileFunction(tau_values), reps=300, method="percentile", size=CONFIDENCE),
             lambda: library.create_performance_profile({"a": scores}, tau_values, reps=300)[1]["a"]),
        ]:
            np.random.seed(11)
            a = direct()
            np.random.seed(11)
            b = through()
            table.add("mixed", "normal", f"{kind} CI: rliable class vs library function",
                      float(np.max(np.abs(a - b))), 0.0, 0.0)

    # The comparison.
    notes = []
    for name, (taus, algorithms) in cases.items():
        view = candidates.get(name)
        if view is None:
            continue
        names = list(algorithms)
        first = algorithms[names[0]]
        table.add(name, "-", "reps", float(view["reps"] or -1), float(reps), 0.0)
        table.add(name, "-", "confidence", float(view["confidence"] or -1), CONFIDENCE, 0.0)
        if view["tasks"] is None or sorted(view["tasks"]) != sorted(task_names(first)):
            table.fail(name, "-", "tasks", f"{view['tasks']} != {task_names(first)}")
        want_taus = np.linspace(*taus)
        got_taus = view["taus"] or []
        if len(got_taus) != len(want_taus):
            table.fail(name, "-", "taus", f"{len(got_taus)} taus, want {len(want_taus)}")
        else:
            for i, (g, w) in enumerate(zip(got_taus, want_taus)):
                table.point(name, "-", f"tau[{i}]", float(g), float(w))
            inexact = sum(float(g) != float(w) for g, w in zip(got_taus, want_taus))
            if inexact:
                notes.append(f"{name}: {inexact} of apo's {len(want_taus)} taus are not bit-equal to "
                             f"numpy.linspace{taus} (within {POINT_TOL:g}; the profiles were compared at "
                             f"apo's taus; numpy computes LO + i (HI - LO)/(N - 1) and sets the last to HI)")
        for algo in names:
            scores = algorithms[algo]
            got = view["aggregates"].get(algo)
            ref = reference[(name, "aggregates", algo)]
            if got is None:
                table.fail(name, algo, "aggregates", "missing")
            else:
                points = aggregates(scores)
                for i, a in enumerate(AGGREGATES):
                    if a not in got:
                        table.fail(name, algo, a, "missing")
                        continue
                    point, lower, upper = got[a]
                    table.point(name, algo, a, point, float(points[i]))
                    table.endpoint(name, algo, f"{a}.lower", lower, float(ref["lower"][i]),
                                   (float(ref["lower_band"][0][i]), float(ref["lower_band"][1][i])))
                    table.endpoint(name, algo, f"{a}.upper", upper, float(ref["upper"][i]),
                                   (float(ref["upper_band"][0][i]), float(ref["upper_band"][1][i])))
        for i, x in enumerate(names):
            for y in names[i + 1:]:
                ref = reference[(name, "improvement", (x, y))]
                lower_band = (float(ref["lower_band"][0][0]), float(ref["lower_band"][1][0]))
                upper_band = (float(ref["upper_band"][0][0]), float(ref["upper_band"][1][0]))
                # (y, x): mirror of (x, y); its lower end is 1 - (x, y)'s upper end.
                orders = [
                    ((x, y), float(ref["lower"][0]), float(ref["upper"][0]), lower_band, upper_band),
                    ((y, x), 1.0 - float(ref["upper"][0]), 1.0 - float(ref["lower"][0]),
                     (1.0 - upper_band[1], 1.0 - upper_band[0]), (1.0 - lower_band[1], 1.0 - lower_band[0])),
                ]
                for (a, b), ref_lower, ref_upper, band_lower, band_upper in orders:
                    subject = f"P({a} > {b})"
                    got = view["improvement"].get((a, b))
                    if got is None:
                        if not args.self_test or (a, b) == (y, x):
                            table.fail(name, subject, "probability_of_improvement", "missing")
                        continue
                    want = float(metrics.probability_of_improvement(algorithms[a], algorithms[b]))
                    table.point(name, subject, "point", got[0], want)
                    table.endpoint(name, subject, "lower", got[1], ref_lower, band_lower)
                    table.endpoint(name, subject, "upper", got[2], ref_upper, band_upper)
        extra = set(view["improvement"]) - {(a, b) for a in names for b in names if a != b}
        for a, b in sorted(extra):
            table.fail(name, f"P({a} > {b})", "probability_of_improvement", "unexpected pair")
        for algo in names:
            got = view["profiles"].get(algo)
            ref = reference[(name, "profile", algo)]
            tau_values = np.array(view["taus"], dtype=float) if len(got_taus) == len(want_taus) else want_taus
            fractions = library.score_distributions(algorithms[algo], tau_values)
            if got is None or len(got[0]) != len(fractions):
                table.fail(name, algo, "profile", "missing or of the wrong length")
                continue
            for i, tau in enumerate(tau_values):
                label = f"profile@{tau:g}"
                table.point(name, algo, label, got[0][i], float(fractions[i]))
                table.endpoint(name, algo, f"{label}.lower", got[1][i], float(ref["lower"][i]),
                               (float(ref["lower_band"][0][i]), float(ref["lower_band"][1][i])))
                table.endpoint(name, algo, f"{label}.upper", got[2][i], float(ref["upper"][i]),
                               (float(ref["upper_band"][0][i]), float(ref["upper_band"][1][i])))
        if set(view["aggregates"]) - set(names) or set(view["profiles"]) - set(names):
            table.fail(name, "-", "algorithms", f"unexpected algorithms in {sorted(view['aggregates'])}")

    failed = table.print()
    for note in notes:
        print(f"note: {note}")
    total = time.monotonic() - start
    print(f"\ntimes: apo {apo_seconds:.1f} s, rliable bootstraps {rliable_seconds:.1f} s "
          f"({args.jobs} process(es)), total {total:.1f} s")
    print(f"check_rliable: {len(table.rows)} compared, {failed} failed")
    return 1 if failed else 0


def main() -> int:
    argv = sys.argv[1:]
    args = parse_args(argv)
    if args.in_venv:
        return venv_main(args)
    return host_main(args, [a for a in argv if a != "--in-venv"])


if __name__ == "__main__":
    sys.exit(main())
