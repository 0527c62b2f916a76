#!/usr/bin/env bash
# How often a SIGTERM to `mpirun` ends a 2-rank run with its checkpoint and rank 0's report,
# for a given Open MPI grace period (docs/distributed.md, "Files, resume, failures").
#
#   bash scripts/mpi-signal-grace.sh [GRACE_S] [TRIES] [BUSY_LOOPS]
#
# GRACE_S (default 1, Open MPI's own) becomes `--mca odls_base_sigkill_timeout`; BUSY_LOOPS
# (default 0) shell loops load the machine meanwhile. Needs `cargo build -p apo-cli --features mpi`
# (the binary is taken from target/release, else target/debug). Prints one line per try and a
# summary; the runs go to a temporary folder that is removed at the end.
set -euo pipefail
cd "$(dirname "$0")/.."
grace=${1:-1}
tries=${2:-12}
busy=${3:-0}
apo=target/release/apo
[ -x "$apo" ] || apo=target/debug/apo
if [ ! -x "$apo" ]; then
  echo "error: no apo binary; build it with: cargo build -p apo-cli --features mpi" >&2
  exit 1
fi
work=$(mktemp -d)
loops=()
cleanup() {
  for p in "${loops[@]}"; do kill "$p" 2>/dev/null || true; done
  rm -rf "$work"
}
trap cleanup EXIT
for _ in $(seq "$busy"); do
  (while :; do :; done) &
  loops+=($!)
done
reported=0
for i in $(seq "$tries"); do
  run="$work/run$i"
  mpirun --allow-run-as-root --oversubscribe --mca odls_base_sigkill_timeout "$grace" -n 2 \
    "$apo" train --algo apo --env Pendulum-v1 --steps-per-epoch 800 --epochs 100000 --quiet \
    --out "$run" --seed 3 >"$work/out$i" 2>/dev/null &
  pid=$!
  while [ ! -e "$run/progress.csv" ]; do sleep 0.1; done
  sleep 1
  start=$(date +%s.%N)
  kill -TERM "$pid"
  wait "$pid" || true
  end=$(date +%s.%N)
  if grep -q "checkpoint written" "$work/out$i"; then
    ok=yes
    reported=$((reported + 1))
  else
    ok=no
  fi
  awk -v i="$i" -v ok="$ok" -v s="$start" -v e="$end" \
    'BEGIN { printf "try %d: checkpoint reported: %s; mpirun ended %.1f s after the signal\n", i, ok, e - s }'
done
echo "grace ${grace} s, ${busy} busy loops: ${reported} of ${tries} runs checkpointed and reported"
