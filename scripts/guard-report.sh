#!/usr/bin/env bash
# Learning benchmark on GUARD: APO, PAPO, TRPO and PPO on SUITES (default Goal_Point,
# Push_Point, Chase_Point), seeds 0..SEEDS-1 (default 2), EPOCHS x STEPS environment steps each
# (default 50 x 10 000 = 500 000, a reduced budget: the paper runs 200 x 30 000), episodes of
# 1 000 steps. Then the paper's four metrics over the last LAST epochs (default 10) per run and
# one plot per suite and seed.
#   bash scripts/guard-report.sh [OUT_DIR]        (needs target/release/apo)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-runs/guard-report}
epochs=${EPOCHS:-50}
steps=${STEPS:-10000}
seeds=${SEEDS:-2}
jobs=${JOBS:-2}
last=${LAST:-10}
suites=${SUITES:-Goal_Point Push_Point Chase_Point}
apo=./target/release/apo
mkdir -p "$out"
for suite in $suites; do
  for seed in $(seq 0 $((seeds - 1))); do
    for algo in apo papo trpo ppo; do
      echo "$suite $algo $seed"
    done
  done
done | xargs -P "$jobs" -L 1 sh -c \
  "$apo"' train --config configs/guard/$1.toml --env $0 --seed $2 --epochs '"$epochs"' --steps-per-epoch '"$steps"' --out '"$out"'/$0-$1-s$2 --force --quiet'
"$apo" summary --csv --last "$last" "$out"/*-s* | tee "$out/summary.csv"
for suite in $suites; do
  for seed in $(seq 0 $((seeds - 1))); do
    "$apo" plot "$out/$suite"-{apo,papo,trpo,ppo}-s"$seed" --out "$out/$suite-s$seed.png"
  done
done
# Mean ± std over seeds of each metric, per suite and algorithm (Markdown).
awk -F, 'NR > 1 {
  n = split($1, path, "/"); split(path[n], part, "-");
  key = part[1] " | " part[2]; runs[key]++;
  for (c = 4; c <= 7; c++) { sum[key, c] += $c; sq[key, c] += $c * $c }
}
END {
  print "| suite | algo | mean return, last N | worst return, last N | mean return, all epochs | worst return, all epochs |";
  print "|---|---|---|---|---|---|";
  for (key in runs) {
    line = "| " key;
    split("5 7 4 6", cols, " ");
    for (i = 1; i <= 4; i++) {
      c = cols[i]; m = sum[key, c] / runs[key]; v = sq[key, c] / runs[key] - m * m;
      line = line sprintf(" | %.2f ± %.2f", m, sqrt(v > 0 ? v : 0));
    }
    print line " |";
  }
}' "$out/summary.csv" | { read -r h1; read -r h2; echo "$h1"; echo "$h2"; sort; } | tee "$out/summary.md"
