#!/usr/bin/env bash
# Epoch wall time, env steps/s and the time split (rollout, update, MPI collectives) of APO on
# Hopper at 30 000 steps per epoch, on 1 rank (2 environment threads) and 2 ranks (1 thread
# each) of this machine. Needs the release binary built with the `mpi` feature:
#   cargo build --release -p apo-cli --features mpi
#   bash scripts/mpi-bench.sh [EPOCHS] [OUT_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
epochs="${1:-3}"
out="${2:-runs/mpi-bench}"
apo=target/release/apo
mkdir -p "$out"
run() {
  local ranks="$1" threads="$2" dir="$out/n$1"
  mpirun --allow-run-as-root --oversubscribe -n "$ranks" "$apo" train --algo apo --env Hopper \
    --steps-per-epoch 30000 --epochs "$epochs" --threads "$threads" --quiet --force --out "$dir" \
    | tee "$dir.stdout"
}
run 1 2
run 2 1
for n in 1 2; do
  echo "== $n rank(s): epoch, time_s, rollout_s, update_pi_s, update_v_s, steps_per_s"
  python3 - "$out/n$n/progress.csv" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
prev = 0.0
for r in rows:
    t = float(r["time_s"])
    print(r["epoch"], round(t - prev, 2), round(float(r["rollout_s"]), 2),
          round(float(r["update_pi_s"]), 2), round(float(r["update_v_s"]), 2),
          round(float(r["steps_per_s"])))
    prev = t
PY
  grep "^MPI" "$out/n$n.stdout" || true
done
