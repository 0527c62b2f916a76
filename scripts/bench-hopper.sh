#!/usr/bin/env bash
# Learning benchmark on MuJoCo Hopper: APO, PAPO, TRPO, PPO, one seed, EPOCHS x STEPS
# environment steps each (defaults 75 x 4000 = 300 000), then the paper's metrics over the last
# 10 epochs and the plot.   bash scripts/bench-hopper.sh [OUT_DIR]   (needs target/release/apo)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-runs/bench-hopper}
epochs=${EPOCHS:-75}
steps=${STEPS:-4000}
jobs=${JOBS:-2}
seed=${SEED:-0}
apo=./target/release/apo
mkdir -p "$out"
printf '%s\n' apo papo trpo ppo | xargs -P "$jobs" -I{} \
  "$apo" train --algo {} --env Hopper --seed "$seed" --epochs "$epochs" --steps-per-epoch "$steps" \
    --out "$out/Hopper-{}-s$seed" --force --quiet
"$apo" summary --csv --last 10 "$out"/Hopper-*-s"$seed" | tee "$out/summary.csv"
"$apo" plot "$out"/Hopper-{apo,papo,trpo,ppo}-s"$seed" --out "$out/hopper-s$seed.png"
