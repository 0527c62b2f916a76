#!/usr/bin/env bash
# The paper's own budget on two GUARD suites (docs/results/paper-budget.md): 200 epochs x 30 000
# steps (6 M steps per run, the paper's), seeds 0..4, of
#   paper APO and paper PAPO at the omega1 the GUARD campaign tuned for the suite at 1 M steps
#     (results/guard-campaign/tune/<suite>/<algo>/cells.csv; omega2 as in the campaign),
#   robust PAPO (--preset robust), TRPO and PPO.
# The two suites come from a rule written down before any of these runs
# (scripts/paper-budget-suites.py: the two where TRPO's worst return still rises most over the
# last 20 epochs at 1 M): Goal_Arm3 and Goal_Swimmer.
# Every cell is an `apo sweep`, so the script is resumable: run it again and finished runs are
# skipped (also those kept as config.toml + progress.csv only), interrupted ones resumed from
# their checkpoint. Runs at nice 19, JOBS at once (default 1), one thread each.
#   bash scripts/paper-budget.sh [OUT]   (default results/paper-budget; needs target/release/apo,
#                                         or APO=path/to/apo)
# Cells run seed-major (all five algorithms of seed 0, then seed 1, ...) so that whatever has
# finished when the script is stopped compares the algorithms on the same seeds: one sweep per
# seed and cell, OUT/<suite>/s<seed>/{apo,papo,papo-robust,baselines}.
# Then: apo report OUT/<suite> --last 20 --out <report folder>
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-results/paper-budget}
epochs=${EPOCHS:-200}
steps=${STEPS:-30000}
jobs=${JOBS:-1}
suites=${SUITES:-Goal_Arm3 Goal_Swimmer}
seeds=${SEEDS:-0 1 2 3 4}
apo=${APO:-./target/release/apo}
campaign=${CAMPAIGN:-results/guard-campaign}
# a finished campaign is kept packed (results/<name>.tar.xz): unpacked here when needed
bash scripts/results.sh need "$campaign"
[ -x "$apo" ] || { echo "error: $apo is missing: cargo build --release -p apo-cli" >&2; exit 1; }
omega2() { case $1 in apo) echo 0.007 ;; papo) echo 0.003 ;; esac; }
# the omega1 the campaign picked (cells.csv lists each algorithm's cells best first)
best() {
  local cells="$campaign/tune/$1/$2/cells.csv"
  [ -f "$cells" ] || { echo "error: $cells is missing: the campaign's tuning of $2 on $1" >&2; exit 1; }
  awk -F, '$8 == "true" { gsub(/"/, "", $3); sub(/^omega1=/, "", $3); print $3 }' "$cells"
}
sweep() { nice -n 19 "$apo" sweep --epochs "$epochs" --steps-per-epoch "$steps" --jobs "$jobs" \
  --threads 1 --last 20 --metric worst-last --quiet "$@"; }
for seed in $seeds; do
  for suite in $suites; do
    for algo in apo papo; do
      omega1=$(best "$suite" "$algo")
      echo "== $suite seed $seed: paper $algo, omega1 = $omega1"
      sweep --algo "$algo" --env "$suite" --seeds "$seed" --set "algo.omega1=$omega1" \
        --set "algo.omega2=$(omega2 "$algo")" --out "$out/$suite/s$seed/$algo"
    done
    echo "== $suite seed $seed: papo --preset robust"
    sweep --algo papo --env "$suite" --seeds "$seed" --preset robust --out "$out/$suite/s$seed/papo-robust"
    echo "== $suite seed $seed: trpo, ppo"
    sweep --algo trpo,ppo --env "$suite" --seeds "$seed" --out "$out/$suite/s$seed/baselines"
  done
done
