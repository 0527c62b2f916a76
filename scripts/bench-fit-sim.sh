#!/usr/bin/env bash
# Does the value fit, running beside the next epoch's rollout (the pipelined epoch), slow the
# simulator's step? Times the simulator's own calls (sim_s of `apo bench epoch`) per step over
# epochs 2-6 of APO, 6 epochs x 10 000 steps, 2 threads, pipelined (each of those rollouts runs
# beside the previous epoch's value fit) against --no-pipeline (the fit after the rollout),
# REPS repeats (default 3), on Hopper, Goal_Point, Goal_Swimmer and Push_Hopper.
#   bash scripts/bench-fit-sim.sh            (needs target/release/apo, or APO=path/to/apo)
set -euo pipefail
cd "$(dirname "$0")/.."
apo=${APO:-./target/release/apo}
reps=${REPS:-3}
dir=$(mktemp -d)
for rep in $(seq 1 "$reps"); do
  for env in Hopper Goal_Point Goal_Swimmer Push_Hopper; do
    for mode in pipeline no-pipeline; do
      flag=(); [ "$mode" = no-pipeline ] && flag=(--no-pipeline)
      "$apo" bench epoch --env "$env" --algo apo --steps-per-epoch 10000 --epochs 6 --threads 2 \
        "${flag[@]}" > "$dir/$env.$mode.$rep.txt" 2>&1
    done
  done
done
python3 - "$dir" <<'PY'
import glob, random, re, sys
res = {}
for f in sorted(glob.glob(sys.argv[1] + "/*.txt")):
    env, mode, _ = f.rsplit("/", 1)[1][:-4].split(".")
    hdr, rows = None, []
    for line in open(f).read().splitlines():
        if line.strip().startswith("epoch") and "sim_s" in line:
            hdr = line.split()
        elif hdr and re.match(r"^\s*\d+\s", line):
            rows.append(dict(zip(hdr, line.split())))
    res.setdefault((env, mode), []).extend(
        float(r["sim_s"]) / 10000 * 1e6 for r in rows if int(r["epoch"]) >= 2)
random.seed(0)
med = lambda v: sorted(v)[len(v) // 2]
print("task | µs per simulator step, beside the fit | alone | median ratio, 95 % bootstrap | P(beside > alone)")
for env in ["Hopper", "Goal_Point", "Goal_Swimmer", "Push_Hopper"]:
    p, n = res[(env, "pipeline")], res[(env, "no-pipeline")]
    pi = sum((a > b) + 0.5 * (a == b) for a in p for b in n) / (len(p) * len(n))
    b = sorted(med(random.choices(p, k=len(p))) / med(random.choices(n, k=len(n))) for _ in range(2000))
    print(f"{env} | {med(p):.1f} ({min(p):.1f}-{max(p):.1f}) | {med(n):.1f} ({min(n):.1f}-{max(n):.1f}) | "
          f"{med(p) / med(n):.3f} [{b[50]:.3f}, {b[1949]:.3f}] | {pi:.2f}")
PY
rm -rf "$dir"
