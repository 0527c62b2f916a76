#!/usr/bin/env bash
# The Atari learning report of docs/results/atari.md: APO, PAPO, TRPO and PPO on Pong and
# Riverraid (the paper's ablation game), RAM observations, the paper's settings
# (configs/atari/<algo>.toml: 1 000-step trajectories, (64, 64) tanh networks) at a reduced
# budget, with apo report's tables (the four metrics) and curves.
#   bash scripts/atari-report.sh [OUT_DIR]    (needs target/release/apo built with
#                                              --features atari; resumable)
# EPOCHS x STEPS per run (default 40 x 10 000; the paper: 500 x 30 000), SEEDS seeds
# (default 2), JOBS runs at once (default 2), LAST: N of "the last N epochs" (default 10;
# the paper: 100).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-runs/atari}
last=${LAST:-10}
apo=${APO:-./target/release/apo}
# the settings of configs/atari/*.toml (a test checks they are the defaults with these two)
"$apo" sweep --algo apo,papo,trpo,ppo --env ALE/Pong-v5,ALE/Riverraid-v5 \
  --seeds "0..${SEEDS:-2}" --set max_episode_steps=1000 \
  --epochs "${EPOCHS:-40}" --steps-per-epoch "${STEPS:-10000}" --out "$out" \
  --jobs "${JOBS:-2}" --last "$last" --quiet
"$apo" report "$out" --last "$last" --out "$out/report" > /dev/null
