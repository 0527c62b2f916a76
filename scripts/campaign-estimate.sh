#!/usr/bin/env bash
# How long the paper's GUARD campaign takes on this machine: 12 suites (the 8 low-dimensional ones
# and {Push,Chase}_{Ant,Walker}) x 4 algorithms (APO, PAPO, TRPO, PPO) x 5 seeds x 6 M steps
# (200 epochs x 30 000 steps), run two at a time, as `scripts/paper-budget.sh` runs them.
# For every suite and algorithm, `apo bench epoch` trains EPOCHS (default 3) epochs of the paper's
# 30 000 steps with one environment on one thread, two benches at once (the load of two runs at a
# time), and its end-to-end steps/s (the whole run's steps over its wall time) gives the run's
# hours. Prints a Markdown table per suite and the campaign's total.
#   bash scripts/campaign-estimate.sh [PHYSICS]   (mujoco2, default, or mujoco3: needs a build
#                                                  with --features mujoco3)
#   APO=path/to/apo, SUITES="...", ALGOS="...", EPOCHS=N, STEPS=N to change what is measured.
set -euo pipefail
cd "$(dirname "$0")/.."
physics=${1:-mujoco2}
apo=${APO:-./target/release/apo}
epochs=${EPOCHS:-3}
steps=${STEPS:-30000}
suites=${SUITES:-Goal_Point Goal_Swimmer Goal_Arm3 Goal_Drone Goal_Hopper Push_Point Push_Swimmer Push_Hopper Push_Ant Chase_Ant Push_Walker Chase_Walker}
algos=${ALGOS:-apo papo trpo ppo}
[ -x "$apo" ] || { echo "error: $apo is missing: cargo build --release -p apo-cli" >&2; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for suite in $suites; do for algo in $algos; do echo "$suite $algo"; done; done |
  xargs -P 2 -L 1 sh -c '"$0" bench epoch --env "$5" --algo "$6" --epochs "$1" --steps-per-epoch "$2" \
    --threads 1 --physics "$3" > "$4/$5-$6.txt" 2> "$4/$5-$6.err" || cat "$4/$5-$6.err" >&2' \
    "$apo" "$epochs" "$steps" "$physics" "$tmp"
python3 - "$tmp" "$physics" "$suites" "$algos" <<'PY'
import re, sys, pathlib
tmp, physics, suites, algos = sys.argv[1], sys.argv[2], sys.argv[3].split(), sys.argv[4].split()
run_steps, seeds, at_once = 6_000_000, 5, 2
print(f"physics {physics}; end-to-end steps/s of each algorithm (one environment, one thread, two benches at once),")
print(f"and the hours of the suite's {len(algos)} x {seeds} runs of {run_steps:,} steps run {at_once} at a time\n")
print("| suite | " + " | ".join(algos) + " | simulator share (mean) | hours |")
print("|---|" + "---|" * (len(algos) + 2))
total, missing = 0.0, []
for suite in suites:
    rates, shares = [], []
    for algo in algos:
        f = pathlib.Path(tmp, f"{suite}-{algo}.txt")
        m = f.exists() and re.search(r"^end_to_end: steps=\d+ wall_s=[\d.]+ steps_per_s=(\d+) .* sim_share=([\d.]+)", f.read_text(), re.M)
        if not m:
            missing.append(f"{suite} {algo}")
            rates.append(None)
            continue
        rates.append(float(m.group(1)))
        shares.append(float(m.group(2)))
    hours = sum(seeds * run_steps / r / 3600 for r in rates if r) / at_once
    total += hours
    cells = " | ".join(f"{r:,.0f}" if r else "—" for r in rates)
    share = f"{sum(shares) / len(shares):.2f}" if shares else "—"
    print(f"| {suite} | {cells} | {share} | {hours:.1f} |")
print(f"\ncampaign: {total:.1f} h on this machine, {len(suites)} suites x {len(algos)} algorithms x {seeds} seeds")
if missing:
    print("not measured (their bench failed): " + ", ".join(missing), file=sys.stderr)
    sys.exit(1)
PY
