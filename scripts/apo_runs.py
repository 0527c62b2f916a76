"""What the report scripts share about a run folder (config.toml + progress.csv as `apo train`
writes them). Imported by scripts/campaign-diagnostics.py and scripts/variants-steps.py; Python
puts a script's own folder on the import path, so `import apo_runs` works from any directory."""
import csv
import os
import tomllib


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
