#!/usr/bin/env bash
# The ablation of APO's variants (docs/results/variants.md): the paper's APO, each variant alone,
# the recommended combination (--preset robust) and TRPO, and PAPO's side of it (the paper's PAPO,
# PAPO with --preset robust, PPO), on Hopper-v4 (EPOCHS_HOPPER x STEPS,
# default 50 x 10 000 = 0.5 M steps, a reduced budget) and Goal_Point (the GUARD campaign's budget,
# 100 x 10 000 = 1 M), seeds 0..4. On Goal_Point the TRPO, PPO and paper-PAPO runs are the
# campaign's (results/guard-campaign/eval/Goal_Point), run with the same settings.
# Every cell is an `apo sweep`: resumable, finished runs are skipped. Runs at nice 19.
#   bash scripts/variants-ablation.sh [OUT]   (default results/variants/ablation; JOBS=2)
# Then: apo report OUT/*/* --last 10 --out OUT/report
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-results/variants/ablation}
jobs=${JOBS:-1}
steps=${STEPS:-10000}
apo=${APO:-./target/release/apo}
[ -x "$apo" ] || { echo "error: $apo is missing: cargo build --release -p apo-cli" >&2; exit 1; }
# the robust preset's omega (crates/apo-cli/src/config.rs), for the scale-free penalty alone
robust_omega=(--set algo.omega1=0.01 --set algo.omega2=0.005)
cells=${CELLS:-paper units=advantage switch=held switch=off acceptance=ratio robust trpo papo papo-robust ppo}
for env in ${ENVS:-Hopper-v4 Goal_Point}; do
  case $env in Hopper-v4) epochs=${EPOCHS_HOPPER:-50} ;; *) epochs=${EPOCHS_GUARD:-100} ;; esac
  sweep() { nice -n 19 "$apo" sweep --env "$env" --seeds 0..5 --epochs "$epochs" --steps-per-epoch "$steps" \
    --jobs "$jobs" --threads 1 --quiet --last 10 --metric worst-last "$@"; }
  for cell in $cells; do
    case $cell in
      paper) sweep --algo apo --out "$out/$env/$cell" ;;
      units=advantage) sweep --algo apo --set algo.penalty_units=advantage "${robust_omega[@]}" --out "$out/$env/$cell" ;;
      switch=*|acceptance=*) key=${cell%%=*}; [ "$key" = acceptance ] && key=trust_region.acceptance
        sweep --algo apo --set "algo.$key=${cell#*=}" --out "$out/$env/$cell" ;;
      robust) sweep --algo apo --preset robust --out "$out/$env/$cell" ;;
      papo-robust) sweep --algo papo --preset robust --out "$out/$env/$cell" ;;
      trpo|papo|ppo) [ "$env" = Goal_Point ] || sweep --algo "$cell" --out "$out/$env/$cell" ;;
      *) echo "error: unknown cell $cell" >&2; exit 2 ;;
    esac
  done
done
