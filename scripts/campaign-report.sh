#!/usr/bin/env bash
# The GUARD campaign's report with its robust column (docs/results/guard-campaign.md): the
# evaluation runs of every suite (CAMPAIGN/eval/<suite>/{apo,papo,baselines}) and, beside them,
# APO and PAPO with --preset robust (ROBUST/<suite>/{robust,papo-robust}, the variants'
# ablation folders) copied under names `apo report` groups apart (<suite>-apo-robust-s<seed>,
# <suite>-papo-robust-s<seed>); only suites whose runs have all finished (LAST_EPOCH, default 100)
# are reported. Then `apo report` over the last LAST epochs (default 20, the campaign's).
#   bash scripts/campaign-report.sh [OUT]   (default /tmp/campaign-report; CAMPAIGN, ROBUST, SUITES)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-/tmp/campaign-report}
campaign=${CAMPAIGN:-results/guard-campaign}
robust=${ROBUST:-results/variants/ablation}
apo=${APO:-./target/release/apo}
last_epoch=${LAST_EPOCH:-100}
# a finished campaign is kept packed (results/<name>.tar.xz): unpacked here when needed
bash scripts/results.sh need "$campaign" "$robust"
runs="$out/runs"
rm -rf "$runs"
mkdir -p "$runs"
finished() { [ -f "$1/progress.csv" ] && [ "$(tail -n 1 "$1/progress.csv" | cut -d, -f1)" = "$last_epoch" ]; }
for suite in ${SUITES:-$(ls "$campaign/eval")}; do
  list=()
  for run in "$campaign/eval/$suite"/{apo,papo,baselines}/"$suite"-*-s[0-9]*; do
    [ -d "$run" ] && list+=("$run|$(basename "$run")")
  done
  for cell in robust papo-robust; do
    for run in "$robust/$suite/$cell/$suite"-*-s[0-9]*; do
      [ -d "$run" ] || continue
      base=$(basename "$run")
      list+=("$run|${base%-s*}-robust-${base##*-}")
    done
  done
  # 4 algorithms x 5 seeds, and 2 robust cells x 5 seeds
  complete=1
  [ "${#list[@]}" -eq 30 ] || complete=0
  for item in "${list[@]}"; do finished "${item%%|*}" || complete=0; done
  if [ "$complete" = 0 ]; then
    echo "skipping $suite: ${#list[@]} of 30 runs, not all finished" >&2
    continue
  fi
  for item in "${list[@]}"; do
    dest="$runs/${item##*|}"
    mkdir -p "$dest"
    cp "${item%%|*}/config.toml" "${item%%|*}/progress.csv" "$dest/"
    # every episode, where the run recorded them (`apo report` recomputes the returns from it)
    if [ -f "${item%%|*}/episodes.csv" ]; then cp "${item%%|*}/episodes.csv" "$dest/"; fi
  done
done
"$apo" report "$runs" --last "${LAST:-20}" --out "$out/report"
