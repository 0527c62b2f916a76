#!/usr/bin/env bash
# The field's worst-case methods under one protocol (docs/results/worst-case-methods.md, where the
# protocol is written down): MVPI, CVaR PPO, return capping and apo's tail-weighted PPO (tailppo),
# each with its one risk parameter picked on the tuning tasks and seeds of `--preset robust`, then
# run on the 8 GUARD suites of the campaign (docs/results/guard-campaign.md) at its budget, beside
# its TRPO, PPO, APO and PAPO runs.
#   bash scripts/worst-case-methods.sh tune [OUT]  each method's grid on Hopper-v4 and Goal_Point,
#                                                  seeds 100-101, 30 epochs x 10 000 steps
#   bash scripts/worst-case-methods.sh pick [OUT]  the value the rule picks for each method
#                                                  (scripts/worst-case-pick.py)
#   bash scripts/worst-case-methods.sh eval [OUT]  8 GUARD suites x seeds 0-4, 100 epochs x
#                                                  10 000 steps, at the picked values
# (OUT defaults to results/worst-case-methods). Every cell is an `apo sweep`: run the script again
# to continue (finished runs are skipped, interrupted ones resumed from their checkpoint). Runs at
# nice 19, JOBS at once (default 1), one thread each; needs target/release/apo (or APO=path).
# Then: apo report results/worst-case-methods/eval/<suite>/* <the campaign's runs> --last 20
set -euo pipefail
cd "$(dirname "$0")/.."
phase=${1:-}
out=${2:-results/worst-case-methods}
jobs=${JOBS:-1}
apo=${APO:-./target/release/apo}
# method:key:grid (the grid's middle is the method's default)
methods=${METHODS:-"mvpi:mv_lambda:0.01,0.1,1 cvar:alpha:0.1,0.2,0.5 retcap:alpha:0.1,0.2,0.5 tailppo:tail_weight:2,4,8"}
suites=${SUITES:-Goal_Point Push_Point Goal_Swimmer Push_Swimmer Goal_Arm3 Goal_Drone Goal_Hopper Push_Hopper}
[ -x "$apo" ] || { echo "error: $apo is missing: cargo build --release -p apo-cli" >&2; exit 1; }
sweep() { nice -n 19 "$apo" sweep --jobs "$jobs" --threads 1 --metric worst-last --quiet "$@"; }
case $phase in
  tune)
    for task in Hopper-v4 Goal_Point; do
      for m in $methods; do
        IFS=: read -r algo key grid <<< "$m"
        echo "== tuning $algo ($key in $grid) on $task"
        sweep --algo "$algo" --env "$task" --seeds 100,101 --epochs 30 --steps-per-epoch 10000 \
          --last 10 --grid "algo.$key=$grid" --out "$out/tune/$task/$algo"
      done
    done ;;
  pick)
    python3 scripts/worst-case-pick.py "$out/tune" ;;
  eval)
    picked=$(python3 scripts/worst-case-pick.py "$out/tune" --values)
    for suite in $suites; do
      for m in $methods; do
        IFS=: read -r algo key _ <<< "$m"
        value=$(awk -v a="$algo" '$1 == a { print $2 }' <<< "$picked")
        [ -n "$value" ] || { echo "error: no value picked for $algo (run the tune phase first)" >&2; exit 1; }
        echo "== $suite: $algo with $key = $value"
        sweep --algo "$algo" --env "$suite" --seeds 0..5 --epochs 100 --steps-per-epoch 10000 \
          --last 20 --set "algo.$key=$value" --out "$out/eval/$suite/$algo"
      done
    done ;;
  *) echo "usage: bash scripts/worst-case-methods.sh tune|pick|eval [OUT]" >&2; exit 2 ;;
esac
