#!/usr/bin/env bash
# The report of the variants' ablation (docs/results/variants.md): every cell's runs copied under
# names that tell the cells apart (<env>-<algo>-<cell>-s<seed>; `apo report` groups runs by
# name; the paper's algorithms keep their names, PAPO's robust cell is <env>-papo-robust), the
# GUARD campaign's TRPO, PPO and PAPO runs of each GUARD suite beside them, then `apo report`.
#   bash scripts/variants-report.sh [ABLATION] [OUT]   (defaults results/variants/ablation, /tmp/variants-report)
# The held-out comparison's folder (results/variants/heldout) works too: its baselines keep their
# names, its robust-<algos> runs become <env>-<algo>-robust.
# ALGOS (default all) keeps only these algorithms' runs, e.g. ALGOS="apo trpo" for APO's side: the
# report's statistics cover the environments every group has, and PAPO's cells run on fewer.
set -euo pipefail
cd "$(dirname "$0")/.."
src=${1:-results/variants/ablation}
out=${2:-/tmp/variants-report}
apo=${APO:-./target/release/apo}
# a finished campaign is kept packed (results/<name>.tar.xz): unpacked here when needed
bash scripts/results.sh need "$src" results/guard-campaign
runs="$out/runs"
keep() { [ -z "${ALGOS:-}" ] || [[ " $ALGOS " == *" $1 "* ]]; }
# a run counts once its last epoch is the one its config.toml asks for (runs still going are left out)
finished() {
  local want
  want=$(awk -F' = ' '$1 == "epochs" { print $2; exit }' "$1/config.toml")
  [ -n "$want" ] && [ "$(tail -n 1 "$1/progress.csv" | cut -d, -f1)" = "$want" ]
}
rm -rf "$runs"
mkdir -p "$runs"
for cell in "$src"/*/*/; do
  name=$(basename "$cell")
  for run in "$cell"*-s[0-9]*/; do
    [ -f "$run/progress.csv" ] && finished "$run" || continue
    base=$(basename "$run")
    stem=${base%-s*}
    keep "${stem##*-}" || continue
    case $name in
      trpo|papo|ppo|baselines|baselines-*) dest="$runs/$base" ;;
      robust-*) dest="$runs/$stem-robust-${base##*-}" ;;
      *) dest="$runs/$stem-${name#papo-}-${base##*-}" ;;
    esac
    mkdir -p "$dest"
    cp "$run/config.toml" "$run/progress.csv" "$dest/"
  done
done
for suite in "$src"/*_*/; do
  suite=$(basename "$suite")
  for run in results/guard-campaign/eval/"$suite"/{baselines,papo}/"$suite"-{trpo,ppo,papo}-s*/; do
    [ -f "$run/progress.csv" ] && finished "$run" || continue
    base=$(basename "$run")
    stem=${base%-s*}
    keep "${stem##*-}" || continue
    dest="$runs/$base"
    mkdir -p "$dest"
    cp "$run/config.toml" "$run/progress.csv" "$dest/"
  done
done
"$apo" report "$runs" --last "${LAST:-10}" --out "$out/report"
