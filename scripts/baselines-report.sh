#!/usr/bin/env bash
# The benchmark of docs/results/baselines.md: APO, PAPO and the six baselines (TRPO, PPO, A2C,
# ESPO, AlphaPPO, V-MPO) on Hopper and on the GUARD suite Goal_Point, at a reduced budget, with
# apo report's tables and curves.
#   bash scripts/baselines-report.sh [OUT_DIR]      (needs target/release/apo; resumable)
# Hopper: EPOCHS x STEPS (default 40 x 4 000) per run, HOPPER_SEEDS seeds (default 3);
# Goal_Point: EPOCHS x GUARD_STEPS (default 40 x 10 000: ten 1 000-step episodes per epoch),
# GUARD_SEEDS seeds (default 2); JOBS runs at once (default 2). APO and PAPO use the omega cells
# of configs/tuned/hopper-{apo,papo}.toml on both tasks; everything else is the defaults
# (configs/<algo>.toml, configs/guard/<algo>.toml).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-runs/baselines}
epochs=${EPOCHS:-40}
jobs=${JOBS:-2}
last=${LAST:-10}
apo=${APO:-./target/release/apo}
algos=apo,papo,trpo,ppo,a2c,espo,alphappo,vmpo
tuned=(--grid algo.apo.omega1=0.001 --grid algo.apo.omega2=0.007
       --grid algo.papo.omega1=0.007 --grid algo.papo.omega2=0.003)
"$apo" sweep --algo "$algos" --env Hopper --seeds "0..${HOPPER_SEEDS:-3}" "${tuned[@]}" \
  --epochs "$epochs" --steps-per-epoch "${STEPS:-4000}" --out "$out/hopper" --jobs "$jobs" \
  --last "$last" --quiet
"$apo" sweep --algo "$algos" --env Goal_Point --seeds "0..${GUARD_SEEDS:-2}" "${tuned[@]}" \
  --epochs "$epochs" --steps-per-epoch "${GUARD_STEPS:-10000}" --out "$out/goal-point" \
  --jobs "$jobs" --last "$last" --quiet
for dir in hopper goal-point; do
  "$apo" report "$out/$dir" --last "$last" --out "$out/$dir/report" > /dev/null
done
