#!/usr/bin/env bash
# The ablation of APO's variants (docs/results/variants.md): the paper's APO, each variant alone,
# the recommended combination (--preset robust) and TRPO, and PAPO's side of it (the paper's PAPO,
# PAPO with --preset robust, PPO), on Hopper-v4 (EPOCHS_HOPPER x STEPS, default 100 x 10 000 =
# 1 M steps) and the GUARD suites Goal_Point, Push_Point, Goal_Arm3 (the GUARD campaign's budget,
# EPOCHS_GUARD x STEPS = 100 x 10 000 = 1 M), seeds 0..4. On a GUARD suite the TRPO and PPO runs
# are the campaign's evaluation runs: the cells trpo and ppo run the campaign's own baseline sweep
# (results/guard-campaign/eval/<suite>/baselines, same command, so either script finishes it for
# the other); its paper-PAPO runs need the campaign's tuning and come from
# scripts/campaign-guard.sh only.
# Every cell is an `apo sweep`: resumable, finished runs are skipped. Runs at nice 19.
#   bash scripts/variants-ablation.sh [OUT]   (default results/variants/ablation; JOBS=2)
# Then: apo report OUT/*/* --last 10 --out OUT/report
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-results/variants/ablation}
jobs=${JOBS:-1}
steps=${STEPS:-10000}
apo=${APO:-./target/release/apo}
# a finished campaign is kept packed (results/<name>.tar.xz): unpacked here, to be
# resumed or extended; pack it again after with `bash scripts/results.sh pack variants`
bash scripts/results.sh need "$out" results/guard-campaign
[ -x "$apo" ] || { echo "error: $apo is missing: cargo build --release -p apo-cli" >&2; exit 1; }
# the robust preset's omega (crates/apo-cli/src/config.rs), for the scale-free penalty alone
robust_omega=(--set algo.omega1=0.01 --set algo.omega2=0.005)
cells=${CELLS:-paper units=advantage switch=held switch=off acceptance=ratio robust trpo papo papo-robust ppo}
for env in ${ENVS:-Hopper-v4 Goal_Point Push_Point Goal_Arm3}; do
  case $env in Hopper-v4) epochs=${EPOCHS_HOPPER:-100} ;; *) epochs=${EPOCHS_GUARD:-100} ;; esac
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
      trpo|ppo) case $env in
          *_*) sweep --algo trpo,ppo --out "results/guard-campaign/eval/$env/baselines" ;;
          *) sweep --algo "$cell" --out "$out/$env/$cell" ;;
        esac ;;
      papo) case $env in *_*) ;; *) sweep --algo papo --out "$out/$env/$cell" ;; esac ;;
      *) echo "error: unknown cell $cell" >&2; exit 2 ;;
    esac
  done
done
