#!/usr/bin/env bash
# Speed of every GUARD suite, one environment on one thread (medians of REPEATS runs, default 5):
# 1. `guard_speed`: environment steps/s of GuardEnv under random actions, the bare simulator with
#    the same actions, and mj_step/s of the bare model in mujoco-testspeed's regime;
# 2. mujoco-testspeed itself on the same models (`MODEL STEPS*10 1 0.01`), for comparison.
#   bash scripts/bench-guard.sh [STEPS]        (needs libmujoco-dev; builds the example)
set -euo pipefail
cd "$(dirname "$0")/.."
steps=${1:-20000}
repeats=${REPEATS:-5}
cargo build --release -q -p apo-envs --example guard_speed
./target/release/examples/guard_speed "$steps" "$repeats"
echo
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
ball='    <body name="box" pos="0 0 0.2">\n      <freejoint name="box"/>\n      <geom name="box" type="sphere" size="0.2" density="0.001" friction="1 0.005 0.05"/>\n    </body>\n  </worldbody>'
printf '| model | mujoco-testspeed mj_step/s (median of %s) |\n|---|---|\n' "$repeats"
for model in point swimmer arm3 drone hopper ant walker point+ball swimmer+ball hopper+ball ant+ball walker+ball; do
  robot=${model%+ball}
  file=crates/apo-envs/assets/guard/$robot.xml
  if [ "$model" != "$robot" ]; then
    sed "s#^  </worldbody>#$ball#" "$file" > "$tmp/$robot-push.xml"
    file=$tmp/$robot-push.xml
  fi
  rate=$(for _ in $(seq "$repeats"); do
    mujoco-testspeed "$file" $((steps * 10)) 1 0.01 | sed -n 's/ *Steps per second *: *//p'
  done | sort -n | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)] }')
  echo "| $model | $rate |"
done
