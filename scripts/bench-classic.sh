#!/usr/bin/env bash
# Learning benchmark on classic control: APO, PAPO, TRPO, PPO on Pendulum-v1 and CartPole-v1,
# 3 seeds each, EPOCHS x STEPS environment steps per run (defaults 25 x 4000), then the
# paper's metrics (last 10 epochs) and a plot of one comparison.
#   bash scripts/bench-classic.sh [OUT_DIR]      (needs target/release/apo: cargo build --release)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-runs/bench-classic}
epochs=${EPOCHS:-25}
steps=${STEPS:-4000}
jobs=${JOBS:-2}
apo=./target/release/apo
mkdir -p "$out"
runs=()
for env in Pendulum-v1 CartPole-v1; do
  for algo in apo papo trpo ppo; do
    for seed in 0 1 2; do
      config=()
      if [ "$env" = Pendulum-v1 ] && { [ "$algo" = apo ] || [ "$algo" = papo ]; }; then
        config=(--set algo.omega1=1e-4)
      fi
      dir="$out/$env-$algo-s$seed"
      # skip runs already complete (header + one row per epoch)
      if [ -f "$dir/progress.csv" ] && [ "$(wc -l < "$dir/progress.csv")" -gt "$epochs" ]; then continue; fi
      runs+=("$(echo "$env $algo $seed ${config[*]:-}" | sed 's/ *$//')")
    done
  done
done
printf '%s\n' "${runs[@]}" | xargs -P "$jobs" -L 1 bash -c '
  env=$0 algo=$1 seed=$2; shift 2
  '"$apo"' train --algo "$algo" --env "$env" --seed "$seed" --epochs '"$epochs"' --steps-per-epoch '"$steps"' \
    --out '"$out"'/"$env-$algo-s$seed" --force --quiet "$@" > /dev/null'
"$apo" summary --csv --last 10 "$out"/*/ | tee "$out/summary.csv"
"$apo" plot "$out"/Pendulum-v1-{apo,papo,trpo,ppo}-s0 --out "$out/pendulum-s0.png"
"$apo" plot "$out"/CartPole-v1-{apo,papo,trpo,ppo}-s0 --out "$out/cartpole-s0.png"
