#!/usr/bin/env bash
# Environment steps/s of every MuJoCo task on both physics, side by side: `apo bench env` (one
# environment, random actions, through the registry with its wrappers) on MuJoCo 2.2.2 and on
# MuJoCo 3.17, the median of REPEATS runs (default 3), alternating the two.
#   bash scripts/bench-physics.sh [STEPS] [ENV...]   (default 20000 steps; every Gym task, three
#   GUARD suites and the three hands). Needs `scripts/setup.sh` (which fetches MuJoCo 3.17); builds apo with the feature.
set -euo pipefail
cd "$(dirname "$0")/.."
steps=${1:-20000}
shift || true
envs=("$@")
if [ ${#envs[@]} -eq 0 ]; then
  envs=(InvertedPendulum InvertedDoublePendulum Reacher Swimmer Hopper HalfCheetah Walker2d Ant Humanoid
    HumanoidStandup Goal_Point Push_Ant Chase_Walker HandReachDense HandManipulateBlockDense HandManipulateEggDense)
fi
repeats=${REPEATS:-3}
export MUJOCO_DYNAMIC_LINK_DIR="$PWD/.cache/mujoco-3.17.0/lib"
cargo build --release -q -p apo-cli --features mujoco3
median() { sort -n | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)] }'; }
echo "| task | MuJoCo 2.2.2 steps/s | MuJoCo 3.17 steps/s | 3.17 / 2.2.2 |"
echo "|---|---|---|---|"
for env in "${envs[@]}"; do
  two=(); three=()
  for _ in $(seq "$repeats"); do
    two+=("$(./target/release/apo bench env --env "$env" --steps "$steps" --physics mujoco2 | sed -n 's/^steps_per_sec=//p')")
    three+=("$(./target/release/apo bench env --env "$env" --steps "$steps" --physics mujoco3 | sed -n 's/^steps_per_sec=//p')")
  done
  a=$(printf '%s\n' "${two[@]}" | median)
  b=$(printf '%s\n' "${three[@]}" | median)
  echo "| $env | $a | $b | $(awk -v a="$a" -v b="$b" 'BEGIN { printf "%.2f", b / a }') |"
done
