#!/usr/bin/env bash
# Epoch wall time, env steps/s and the time split (rollout, policy update, value update, MPI
# collectives) of APO on Hopper at 30 000 steps per epoch on this machine: 1 rank with 1
# environment, 1 rank with 2 environments on 2 threads, and 2 ranks (1 environment each).
# Needs the release binary built with the `mpi` feature:
#   cargo build --release -p apo-cli --features mpi
#   bash scripts/mpi-bench.sh [EPOCHS] [OUT_DIR]      (APO=path/to/apo to use another binary)
set -euo pipefail
cd "$(dirname "$0")/.."
epochs="${1:-3}"
out="${2:-runs/mpi-bench}"
apo="${APO:-target/release/apo}"
mkdir -p "$out"
run() {
  local name="$1" ranks="$2" envs="$3" threads="$4" dir="$out/$1"
  mpirun --allow-run-as-root --oversubscribe -n "$ranks" "$apo" train --algo apo --env Hopper \
    --steps-per-epoch 30000 --epochs "$epochs" --num-envs "$envs" --threads "$threads" \
    --quiet --force --out "$dir" > "$dir.stdout"
}
run n1-e1 1 1 1
run n1-e2 1 2 2
run n2-e1 2 1 1
for name in n1-e1 n1-e2 n2-e1; do
  echo "== $name: epoch, epoch_s, rollout_s, update_pi_s, update_v_s, steps_per_s"
  python3 - "$out/$name/progress.csv" <<'PY'
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
  grep "^MPI" "$out/$name.stdout" || true
done
