"""What the report scripts share about a run folder (config.toml + progress.csv as `apo train`
writes them), and where a finished campaign's runs are unpacked. Imported by
scripts/campaign-diagnostics.py, scripts/variants-steps.py and scripts/paper-budget-suites.py;
Python puts a script's own folder on the import path, so `import apo_runs` works from any
directory."""
import csv
import os
import subprocess
import tomllib


def need(*paths):
    """Unpacks the campaign archive (results/<name>.tar.xz) that each of `paths` lies in, when
    it is not unpacked yet: a finished campaign is kept packed (scripts/results.sh)."""
    results_sh = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results.sh")
    subprocess.run(["bash", results_sh, "need", *paths], check=True)


def finished_rows(run):
    """The rows of `run`'s progress.csv (dicts keyed by column) when the run finished — its
    last epoch equals the `epochs` of its own config.toml — else None (a run still going, or
    stopped early, is left out of every figure)."""
    try:
        with open(os.path.join(run, "config.toml"), "rb") as f:
            epochs = tomllib.load(f).get("epochs")
        with open(os.path.join(run, "progress.csv"), newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError:
        return None
    if not rows or epochs is None or int(rows[-1]["epoch"]) != epochs:
        return None
    return rows
