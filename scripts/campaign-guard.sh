#!/usr/bin/env bash
# The GUARD campaign (docs/results/guard-campaign.md): the 8 low-dimensional GUARD suites of the
# paper's APO table x APO, PAPO, TRPO, PPO x 5 seeds, EPOCHS x STEPS environment steps per run
# (default 100 x 10 000 = 1 M, a reduced budget: the paper runs 200 x 30 000).
# Suite by suite:
#  1. tuning: omega1 of APO and of PAPO over {0.001, 0.003, 0.01} on seeds 100 and 101, omega2
#     fixed at its Hopper-best value (docs/results/omega-grid-hopper.md: APO 0.007, PAPO 0.003),
#     the best omega1 by the worst return over the last LAST epochs (default 20), mean over seeds;
#  2. evaluation: seeds 0..4 of APO and PAPO at their picked omega1, and of TRPO and PPO, on seeds
#     never used for tuning;
#  3. the robust column: seeds 0..4 of APO and PAPO with --preset robust, in the variants'
#     ablation folders (ROBUST_OUT/<suite>/{robust,papo-robust}, default results/variants/ablation).
# Every step is an `apo sweep`, so the campaign is resumable: run it again and finished runs are
# skipped (also those kept as config.toml + progress.csv only, as committed under
# results/guard-campaign/), interrupted ones resumed from their checkpoint. Runs at nice 19 so
# that builds keep priority, JOBS runs at once (default 1).
#   bash scripts/campaign-guard.sh [OUT]   (default results/guard-campaign; needs target/release/apo,
#                                           or APO=path/to/apo)
# Then: apo report OUT/eval/*/* --last 20 --out OUT/report (bash scripts/campaign-report.sh adds
# the robust column)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-results/guard-campaign}
epochs=${EPOCHS:-100}
steps=${STEPS:-10000}
jobs=${JOBS:-1}
last=${LAST:-20}
suites=${SUITES:-Goal_Point Push_Point Goal_Swimmer Push_Swimmer Goal_Arm3 Goal_Drone Goal_Hopper Push_Hopper}
robust=${ROBUST_OUT:-results/variants/ablation}
apo=${APO:-./target/release/apo}
# a finished campaign is kept packed (results/<name>.tar.xz): unpacked here, to be
# resumed or extended; pack it again after with `bash scripts/results.sh pack guard-campaign`
bash scripts/results.sh need "$out" "$robust"
[ -x "$apo" ] || { echo "error: $apo is missing: cargo build --release -p apo-cli" >&2; exit 1; }
sweep() { nice -n 19 "$apo" sweep --epochs "$epochs" --steps-per-epoch "$steps" --jobs "$jobs" \
  --last "$last" --metric worst-last --quiet "$@"; }
omega2() { case $1 in apo) echo 0.007 ;; papo) echo 0.003 ;; esac; }
# the best omega1 of a tuning sweep (cells.csv lists each algorithm's cells best first)
best() { awk -F, '$8 == "true" { gsub(/"/, "", $3); sub(/^omega1=/, "", $3); print $3 }' "$1/cells.csv"; }
for suite in $suites; do
  for algo in apo papo; do
    echo "== $suite: tuning $algo"
    sweep --algo "$algo" --env "$suite" --seeds 100,101 --grid algo.omega1=0.001,0.003,0.01 \
      --set "algo.omega2=$(omega2 $algo)" --out "$out/tune/$suite/$algo"
  done
  for algo in apo papo; do
    omega1=$(best "$out/tune/$suite/$algo")
    echo "== $suite: $algo with omega1 = $omega1"
    sweep --algo "$algo" --env "$suite" --seeds 0..5 --set "algo.omega1=$omega1" \
      --set "algo.omega2=$(omega2 $algo)" --out "$out/eval/$suite/$algo"
  done
  echo "== $suite: trpo, ppo"
  sweep --algo trpo,ppo --env "$suite" --seeds 0..5 --out "$out/eval/$suite/baselines"
  # the robust column: APO and PAPO with --preset robust (one omega for every task, never tuned
  # here), the same sweeps as the variants' ablation (scripts/variants-ablation.sh), whose folders
  # they share, so that either script finishes them for the other
  for algo in apo papo; do
    cell=robust; [ "$algo" = papo ] && cell=papo-robust
    echo "== $suite: $algo --preset robust"
    nice -n 19 "$apo" sweep --algo "$algo" --env "$suite" --seeds 0..5 --preset robust \
      --epochs "$epochs" --steps-per-epoch "$steps" --jobs "$jobs" --threads 1 --quiet --last 10 \
      --metric worst-last --out "$robust/$suite/$cell"
  done
done
