#!/usr/bin/env bash
# The experiments of docs/reproducing.md ("ω grid" and "APO against TRPO, PAPO against PPO"),
# at a reduced budget: EPOCHS x STEPS environment steps per run (default 40 x 4 000 = 160 000;
# the paper: 200 x 30 000), seeds 0..SEEDS-1 (default 3), JOBS runs at once (default 2).
#   bash scripts/omega-report.sh [OUT_DIR]      (needs target/release/apo; resumable)
# 1. the paper's 5 x 5 grid of omega1 x omega2 for APO and PAPO on Hopper, with TRPO and PPO;
# 2. APO vs TRPO and PAPO vs PPO with the grid's best cells (by the worst return over the
#    last LAST epochs) on Hopper, Walker2d, HumanoidStandup, Pendulum and CartPole, with the
#    defaults and with --preset paper;
# 3. apo report for each.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-runs}
epochs=${EPOCHS:-40}
steps=${STEPS:-4000}
seeds=${SEEDS:-3}
jobs=${JOBS:-2}
last=${LAST:-10}
apo=./target/release/apo
grid="0.001,0.003,0.005,0.007,0.01"
"$apo" sweep --algo apo,papo,trpo,ppo --env Hopper --seeds "0..$seeds" \
  --grid "algo.omega1=$grid" --grid "algo.omega2=$grid" --epochs "$epochs" \
  --steps-per-epoch "$steps" --out "$out/omega-grid-hopper" --jobs "$jobs" --last "$last" \
  --metric worst-last --quiet
# the best cell of each algorithm (cells.csv lists cells best first per algorithm)
best() { awk -F, -v a="$1" '$2 == a && $7 == "true" { gsub(/"/, "", $3); print $3 }' "$out/omega-grid-hopper/cells.csv"; }
cell() { best "$1" | tr " " "\n" | sed "s/^/--grid algo.$1./"; }
for preset in default paper; do
  flags=()
  [ "$preset" = paper ] && flags=(--preset paper)
  # shellcheck disable=SC2046
  "$apo" sweep --algo apo,trpo,papo,ppo --env Hopper,Walker2d,HumanoidStandup,Pendulum,CartPole \
    --seeds "0..$seeds" $(cell apo) $(cell papo) --epochs "$epochs" --steps-per-epoch "$steps" \
    --out "$out/compare-$preset" --jobs "$jobs" --last "$last" --quiet "${flags[@]}"
done
for dir in omega-grid-hopper compare-default compare-paper; do
  "$apo" report "$out/$dir" --last "$last" --out "$out/$dir/report" > /dev/null
done
