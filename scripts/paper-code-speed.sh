#!/usr/bin/env bash
# Times the paper's published code against `apo train` on the same task, side by side:
# APO, PAPO, TRPO and PPO, whole-process wall time, the two in turn (paper, apo 1 core,
# apo 2 cores), REPEATS times each. Prints a markdown table of the ranges and the ratios.
#
#   bash scripts/paper-code-speed.sh PAPER_CHECKOUT [REPEATS]
#
# PAPER_CHECKOUT: your clone of https://github.com/intelligent-control-lab/Absolute-Policy-Optimization,
# with its Python packages installed (torch, gymnasium[mujoco], scipy, mpi4py).
# Environment: ENV (Gymnasium task without -v4, default Hopper; apo runs ENV-v4),
# EPOCHS (5), STEPS (4000 per epoch), SEED (0), APO (the apo binary, default
# target/release/apo), PYTHON (python3). "1 core" pins both to CPU 0 with taskset, one thread.
# Not run by CI: the paper's code is not a dependency of apo.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
checkout="${1:?usage: bash scripts/paper-code-speed.sh PAPER_CHECKOUT [REPEATS]}"
repeats="${2:-2}"
env="${ENV:-Hopper}" epochs="${EPOCHS:-5}" steps="${STEPS:-4000}" seed="${SEED:-0}"
apo="${APO:-$here/../target/release/apo}" python="${PYTHON:-python3}"
for n in "$repeats" "$epochs" "$steps" "$seed"; do
  [[ "$n" =~ ^[0-9]+$ ]] || { echo "paper-code-speed.sh: '$n' is not a whole number (REPEATS, EPOCHS, STEPS, SEED)" >&2; exit 2; }
done
(( repeats >= 1 && epochs >= 1 && steps >= 1 )) || { echo "paper-code-speed.sh: REPEATS, EPOCHS and STEPS must be at least 1" >&2; exit 2; }
[[ -d "$checkout" ]] || { echo "paper-code-speed.sh: the checkout '$checkout' is not a folder" >&2; exit 2; }
[[ -x "$apo" ]] || { echo "paper-code-speed.sh: no apo binary at '$apo' (cargo build --release -p apo-cli, or set APO)" >&2; exit 2; }
command -v taskset > /dev/null || { echo "paper-code-speed.sh: taskset is missing (apt-get install util-linux)" >&2; exit 2; }
scratch="$(mktemp -d)"
trap 'rm -rf "$scratch"' EXIT

# whole-process wall time of a command, in seconds; its output goes to $scratch/log
wall() {
  local start end
  start=$(date +%s.%N)
  if ! "$@" > "$scratch/log" 2>&1; then
    echo "paper-code-speed.sh: failed: $*" >&2
    tail -20 "$scratch/log" >&2
    exit 1
  fi
  end=$(date +%s.%N)
  awk -v a="$start" -v b="$end" 'BEGIN { printf "%.3f\n", b - a }'
}

echo "task $env(-v4), $epochs epochs x $steps steps, seed $seed, $repeats repeats; load before: $(cut -d' ' -f1-3 /proc/loadavg)" >&2
printf 'algo,contender,seconds\n' > "$scratch/times.csv"
for algo in apo papo trpo ppo; do
  for ((r = 1; r <= repeats; r++)); do
    t=$(wall env OMP_NUM_THREADS=1 taskset -c 0 "$python" "$here/paper_code_run.py" "$checkout" "$algo" \
          --env "$env" --epochs "$epochs" --steps "$steps" --seed "$seed")
    printf '%s,paper,%s\n' "$algo" "$t" >> "$scratch/times.csv"
    for cores in 1 2; do
      out="$scratch/run-$algo-$r-$cores"
      if [[ $cores == 1 ]]; then
        t=$(wall env RAYON_NUM_THREADS=1 taskset -c 0 "$apo" train --env "$env-v4" --algo "$algo" --epochs "$epochs" \
              --steps-per-epoch "$steps" --seed "$seed" --threads 1 --quiet --out "$out")
      else
        t=$(wall "$apo" train --env "$env-v4" --algo "$algo" --epochs "$epochs" \
              --steps-per-epoch "$steps" --seed "$seed" --threads 2 --quiet --out "$out")
      fi
      printf '%s,apo-%s,%s\n' "$algo" "$cores" "$t" >> "$scratch/times.csv"
    done
    echo "$algo repeat $r done" >&2
  done
done
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)" >&2
"$python" - "$scratch/times.csv" <<'EOF_TABLE'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
def span(algo, who):
    t = sorted(float(r["seconds"]) for r in rows if r["algo"] == algo and r["contender"] == who)
    return t[0], t[-1]
print("| | paper's code | apo, 1 core | apo, 2 cores | ratio 1 core | ratio 2 cores |")
print("|---|---|---|---|---|---|")
for algo in ("apo", "papo", "trpo", "ppo"):
    p, a1, a2 = span(algo, "paper"), span(algo, "apo-1"), span(algo, "apo-2")
    ratio = lambda a: f"{p[0] / a[1]:.1f}–{p[1] / a[0]:.1f}×"
    print(f"| {algo.upper()} | {p[0]:.1f}–{p[1]:.1f} s | {a1[0]:.1f}–{a1[1]:.1f} s | "
          f"{a2[0]:.1f}–{a2[1]:.1f} s | {ratio(a1)} | {ratio(a2)} |")
EOF_TABLE
