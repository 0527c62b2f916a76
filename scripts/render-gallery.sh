#!/usr/bin/env bash
# The README's gallery: trains one short run per suite family and renders one episode of each
# as a GIF into docs/img/ (each kept under 1 MB: 240 × 180 frames, one step in 1 to 10).
#   bash scripts/render-gallery.sh [RUNS]   (RUNS: where the runs go, default runs/gallery)
# Needs a release build with the Atari games: cargo build --release -p apo-cli --features atari
# Budgets (reduced, for pictures, not results): Hopper-v4 APO 60 × 4 000 steps, Goal_Point APO
# 30 × 10 000, HandReachDense-v3 PAPO 20 × 4 000, ALE/Pong-v5 PPO 15 × 10 000; one thread each.
set -euo pipefail
cd "$(dirname "$0")/.."
APO_BIN=${APO:-./target/release/apo}
runs=${1:-runs/gallery}
mkdir -p "$runs" docs/img
train() { # name, then train's arguments
  local name=$1
  shift
  if [ ! -d "$runs/$name/checkpoints/latest" ]; then
    "$APO_BIN" train "$@" --threads 1 --quiet --out "$runs/$name" --force
  fi
}
train hopper --algo apo --env Hopper-v4 --epochs 60 --steps-per-epoch 4000
train goal_point --config configs/guard/apo.toml --env Goal_Point --epochs 30 --steps-per-epoch 10000
train hand --config configs/hand/papo.toml --env HandReachDense-v3 --epochs 20 --steps-per-epoch 4000
train pong --config configs/atari/ppo.toml --env ALE/Pong-v5 --epochs 15 --steps-per-epoch 10000
render() { # name, keep one step in N, frames per second
  "$APO_BIN" render --run "$runs/$1" --episodes 1 --deterministic --seed 1 --width 240 --height 180 \
    --every "$2" --fps "$3" --out "docs/img/$1.gif"
}
render hopper 2 25
render goal_point 10 15
render hand 1 25
render pong 4 15
ls -l docs/img/*.gif
