#!/usr/bin/env bash
# The end-to-end table of docs/benchmarks.md ("A run's speed end to end"): for Hopper-v4 at
# 4 000 steps per epoch and Goal_Point, Goal_Swimmer and Push_Hopper at the campaign's 10 000,
# the bare environment (`apo bench env`, random actions) and `apo bench epoch` of APO, PAPO, TRPO
# and PPO (one environment, 2 threads, 5 epochs, pipelined), one markdown row per task and
# algorithm: the end-to-end speed, the simulator's own speed inside the run, the simulator's
# share of the wall time and the rollout's own work per second of simulation (`outside_sim`, the
# median over the steady epochs).
#   bash scripts/bench-end-to-end.sh [TASK...]   (APO=path/to/apo, default target/release/apo;
#                                                 EPOCHS, THREADS; about 2 minutes)
set -euo pipefail
cd "$(dirname "$0")/.."
apo=${APO:-./target/release/apo}
epochs=${EPOCHS:-5}
threads=${THREADS:-2}
[ -x "$apo" ] || { echo "error: $apo is missing: cargo build --release -p apo-cli" >&2; exit 1; }
[[ $epochs =~ ^[0-9]+$ && $epochs -ge 3 ]] || { echo "error: EPOCHS=$epochs: need a whole number of at least 3 (the first and last epochs are not steady)" >&2; exit 2; }
[[ $threads =~ ^[1-9][0-9]*$ ]] || { echo "error: THREADS=$threads: need a whole number of at least 1" >&2; exit 2; }
tasks=("$@")
[ ${#tasks[@]} -gt 0 ] || tasks=(Hopper-v4 Goal_Point Goal_Swimmer Push_Hopper)
field() { sed -n "s/\(^\|.*[ :]\)$1=\([^ ]*\).*/\2/p" | head -1; }
echo "| task | algorithm | end to end, steps/s | the simulator inside the run, steps/s | bare environment, steps/s | simulator's share of the wall time | rollout's own work / simulator time |"
echo "|---|---|---|---|---|---|---|"
for task in "${tasks[@]}"; do
  case $task in Hopper*) steps=4000 ;; *) steps=10000 ;; esac
  bare=$("$apo" bench env --env "$task" --steps $((steps * 5)) | field steps_per_sec)
  for algo in apo papo trpo ppo; do
    out=$("$apo" bench epoch --env "$task" --algo "$algo" --epochs "$epochs" \
      --steps-per-epoch "$steps" --threads "$threads")
    e2e=$(grep '^end_to_end:' <<<"$out")
    printf '| %s | %s | %.0f | %.0f | %.0f | %s | %s |\n' "$task" "$algo" \
      "$(field steps_per_s <<<"$e2e")" "$(field sim_steps_per_s <<<"$e2e")" "$bare" \
      "$(field sim_share <<<"$e2e")" "$(grep '^median_steady' <<<"$out" | field outside_sim)"
  done
done
