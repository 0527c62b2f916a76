#!/usr/bin/env bash
# The held-out comparison of the robust preset (docs/results/variants.md): APO and PAPO with
# --preset robust, chosen on Hopper-v4 and Goal_Point only, against TRPO and PPO on tasks that
# took no part in choosing it: Pendulum-v1, Chase_Point, Walker2d-v4, HalfCheetah-v4, seeds 0..4.
# Budgets: GUARD suites EPOCHS_GUARD x STEPS (default 100 x 10 000 = 1 M, the GUARD campaign's),
# the others EPOCHS x STEPS (default 50 x 10 000 = 0.5 M, the Hopper ablation's; reduced).
# Every cell is an `apo sweep`: resumable, finished runs are skipped. Runs at nice 19. Each
# algorithm list has its own folder: <env>/robust-<algos> and <env>/baselines-<algos>.
#   bash scripts/variants-heldout.sh [OUT]   (default results/variants/heldout; JOBS=2;
#   ROBUST=apo,papo and BASELINES=trpo,ppo choose the algorithms, ENVS the tasks)
# Then: bash scripts/variants-report.sh results/variants/heldout /tmp/heldout-report
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-results/variants/heldout}
jobs=${JOBS:-1}
steps=${STEPS:-10000}
apo=${APO:-./target/release/apo}
# a finished campaign is kept packed (results/<name>.tar.xz): unpacked here, to be
# resumed or extended; pack it again after with `bash scripts/results.sh pack variants`
bash scripts/results.sh need "$out"
[ -x "$apo" ] || { echo "error: $apo is missing: cargo build --release -p apo-cli" >&2; exit 1; }
for env in ${ENVS:-Pendulum-v1 Chase_Point Walker2d-v4 HalfCheetah-v4}; do
  case $env in *_*) epochs=${EPOCHS_GUARD:-100} ;; *) epochs=${EPOCHS:-50} ;; esac
  sweep() { nice -n 19 "$apo" sweep --env "$env" --seeds 0..5 --epochs "$epochs" --steps-per-epoch "$steps" \
    --jobs "$jobs" --threads 1 --quiet --last 10 --metric worst-last "$@"; }
  robust=${ROBUST:-apo,papo}
  baselines=${BASELINES:-trpo,ppo}
  sweep --algo "$robust" --preset robust --out "$out/$env/robust-${robust//,/-}"
  sweep --algo "$baselines" --out "$out/$env/baselines-${baselines//,/-}"
done
