#!/usr/bin/env bash
# Re-runs, with the current binary, every committed run whose progress.csv has an epoch with
# unstable_episodes > 0 and that has no episodes.csv yet (one written by a binary that counts
# every episode), so that its return statistics count the episodes ended by a simulator
# failure (the binaries that wrote the committed runs left them out). Runs are bit-reproducible:
# a re-run differs from the committed one only in those epochs' return columns (check with
# scripts/rerun-compare.py, which also copies the new files over the committed ones).
#
#   bash scripts/rerun-unstable.sh [OUT]        (default OUT=/tmp/rerun-honest)
#
# Each run <root>/<suite>/<cell>/<run> is re-run into OUT/<root>/<suite>/<cell>/<run> (OUT mirrors
# the repository's paths, so `scripts/rerun-compare.py . OUT` pairs them) with
#   nice -n 19 $APO train --config <run>/config.toml --out <dest> --threads 1 --quiet
# Environment:
#   APO     the binary (default ./target/release/apo)
#   JOBS    runs at once (default 1)
#   ROOTS   the roots searched (default: results/guard-campaign/eval results/variants/ablation)
#   SUITES  only these suite folders (names separated by spaces or commas; default all)
#   DRY_RUN=1  only print what would be started, resumed or skipped
# Order: Goal_Drone, Goal_Hopper, Push_Hopper, then the other suites by name; within a suite the
# roots in the order of ROOTS (the campaign's eval runs before the ablation's robust cells).
# Resumable and safe to kill (Ctrl-C or SIGTERM: each running run is sent one SIGTERM, checkpoints
# and stops; a second signal stops them at once) and to start again: a dest whose progress.csv has
# as many rows as the run's `epochs` is skipped, an unfinished one is continued with
# `$APO train --resume <dest>`, one locked by a running apo is left alone ("busy"); a second
# instance into the same OUT refuses to start. Relative paths (OUT, APO, ROOTS) are taken from the
# repository's root. Each run's output is appended to OUT/logs/<its path, / as __>.log.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-/tmp/rerun-honest}
jobs=${JOBS:-1}
apo=${APO:-./target/release/apo}
roots=${ROOTS:-results/guard-campaign/eval results/variants/ablation}
suites_only=${SUITES:-}
dry=${DRY_RUN:-0}
# a finished campaign is kept packed (results/<name>.tar.xz): unpacked here when needed
# shellcheck disable=SC2086
bash scripts/results.sh need $roots
first_suites=(Goal_Drone Goal_Hopper Push_Hopper)

if [ "${BASH_VERSINFO[0]}" -lt 4 ] || { [ "${BASH_VERSINFO[0]}" -eq 4 ] && [ "${BASH_VERSINFO[1]}" -lt 3 ]; }; then
  echo "error: bash 4.3 or later is needed (wait -n); this is $BASH_VERSION" >&2; exit 1
fi
case $jobs in '' | *[!0-9]* | 0) echo "error: JOBS must be a positive integer, not '$jobs'" >&2; exit 2 ;; esac
[ -x "$apo" ] && [ -f "$apo" ] || {
  echo "error: $apo is missing or not executable: cargo build --release -p apo-cli (or set APO)" >&2; exit 1; }
quiet=(--quiet)
help=$("$apo" train --help 2>&1 || true)  # (not piped into grep -q: pipefail and SIGPIPE)
if ! grep -q -- '--quiet' <<<"$help"; then
  echo "note: $apo train has no --quiet; running without it" >&2
  quiet=()
fi
session=()
command -v setsid >/dev/null && session=(setsid)  # runs out of the terminal's Ctrl-C: we pass it on once
# a new session is a new scheduler autogroup (Linux with CONFIG_SCHED_AUTOGROUP), where nice -n 19
# no longer yields to other sessions' work (a build beside the runs got a third of the CPU): each
# run lowers its own group's share too (best effort; /proc/self/autogroup exists only there)
niced=(sh -c 'echo 19 > /proc/self/autogroup 2>/dev/null; exec "$@"' sh)

# the top-level `epochs` key of a config.toml (before its first [table])
config_epochs() { awk '/^[[:space:]]*\[/{exit} /^[[:space:]]*epochs[[:space:]]*=/{sub(/^[^=]*=[[:space:]]*/,""); sub(/[[:space:]#].*$/,""); print; exit}' "$1"; }
# data rows of a progress.csv (0 when missing)
progress_rows() { [ -f "$1" ] && awk 'NR>1 && NF' "$1" | wc -l | tr -d ' ' || echo 0; }
# whether a progress.csv has an epoch with unstable_episodes > 0
has_unstable() {
  awk -F, 'NR==1{for(i=1;i<=NF;i++) if($i=="unstable_episodes") c=i; if(!c) exit; next}
           ($c+0)>0 {found=1; exit} END{exit !found}' "$1"
}
# whether apo holds the run directory's lock (a run in progress)
locked() { [ -f "$1/apo.lock" ] && ! flock -n "$1/apo.lock" true 2>/dev/null; }
wanted_suite() {
  [ -z "$suites_only" ] && return 0
  local s
  for s in ${suites_only//,/ }; do [ "$s" = "$1" ] && return 0; done
  return 1
}

# the suites, in order: the first three, then the others by name
all_suites=$(for r in $roots; do
  if [ -d "$r" ]; then find "$r" -mindepth 1 -maxdepth 1 -type d -printf '%f\n'; fi
done | sort -u)
ordered=()
for s in "${first_suites[@]}"; do grep -qxF "$s" <<<"$all_suites" && ordered+=("$s"); done
while IFS= read -r s; do
  [ -n "$s" ] || continue
  case " ${first_suites[*]} " in *" $s "*) ;; *) ordered+=("$s") ;; esac
done <<<"$all_suites"

# the runs to re-run: <root>/<suite>/**/<run>/ with config.toml and progress.csv
tasks=()
for s in "${ordered[@]}"; do
  wanted_suite "$s" || continue
  for r in $roots; do
    [ -d "$r/$s" ] || continue
    while IFS= read -r p; do
      run=${p%/progress.csv}
      [ -f "$run/config.toml" ] || continue
      # a run that has its episodes.csv was written (or already replaced) by a binary that
      # counts every episode: nothing to re-derive
      [ -f "$run/episodes.csv" ] && continue
      has_unstable "$p" && tasks+=("${run#./}")
    done < <(find "$r/$s" -name progress.csv -type f | LC_ALL=C sort)
  done
done
for r in $roots; do [ -d "$r" ] || echo "warning: root $r is not a directory" >&2; done
for s in ${suites_only//,/ }; do
  grep -qxF "$s" <<<"$all_suites" || echo "warning: no suite folder $s under the roots" >&2
done
case "$(readlink -m "$out")/" in "$(readlink -m results)"/*)
  echo "error: OUT=$out is inside results/: re-run elsewhere, then scripts/rerun-compare.py --replace" >&2; exit 2 ;;
esac
echo "${#tasks[@]} runs with unstable episodes; re-running into $out (JOBS=$jobs)"
[ ${#tasks[@]} -gt 0 ] || exit 0
if [ "$dry" != 1 ]; then
  mkdir -p "$out/logs"
  # one instance per OUT (the runs' own locks also keep a run from being trained twice)
  exec 9>>"$out/.rerun-unstable.lock"
  flock -n 9 || { echo "error: another scripts/rerun-unstable.sh is running into $out" >&2; exit 1; }
fi
failed_list=$(mktemp)
trap 'rm -f "$failed_list"' EXIT

stopping=0
on_signal() {
  stopping=$((stopping + 1))
  if [ $stopping -eq 1 ]; then
    echo "stopping: each running run checkpoints and ends (signal again to stop them at once)" >&2
  fi
  local p
  for p in $(jobs -rp); do kill -TERM "$p" 2>/dev/null || true; done
}
trap on_signal INT TERM

# one run in the background: a subshell that passes each SIGTERM on to apo and reports the end
launch() {
  local name=$1 log=$2; shift 2
  (
    trap '' INT
    ${session[@]+"${session[@]}"} "${niced[@]}" "$@" </dev/null >>"$log" 2>&1 9>&- &
    child=$!
    signalled=0
    trap 'signalled=1; kill -TERM "$child" 2>/dev/null || true' TERM
    rc=0
    while :; do
      wait "$child" && rc=0 || rc=$?
      kill -0 "$child" 2>/dev/null || break
    done
    if [ "$rc" -eq 0 ]; then
      echo "finished $name"
    elif [ "$signalled" -eq 1 ]; then
      echo "stopped  $name (exit $rc; continued on the next start)"
    else
      echo "FAILED   $name (exit $rc; see $log)"
      echo "$name" >>"$failed_list"
    fi
  ) &
}

started=0 skipped=0
for run in "${tasks[@]}"; do
  [ $stopping -eq 0 ] || break
  rel=${run#/}
  dest="$out/$rel"
  log="$out/logs/${rel//\//__}.log"
  epochs=$(config_epochs "$run/config.toml")
  case $epochs in '' | *[!0-9]*) echo "FAILED   $run: no epochs key in its config.toml" >&2; echo "$run" >>"$failed_list"; continue ;; esac
  if [ "$(readlink -f "$dest")" = "$(readlink -f "$run")" ]; then
    echo "error: OUT=$out puts the re-run of $run onto itself" >&2; exit 2
  fi
  if [ -e "$dest" ] && locked "$dest"; then
    echo "busy     $dest (another apo holds its lock)"; skipped=$((skipped + 1)); continue
  fi
  done_rows=$(progress_rows "$dest/progress.csv")
  if [ "$done_rows" -ge "$epochs" ]; then
    echo "skip     $dest (finished, $done_rows/$epochs epochs)"; skipped=$((skipped + 1)); continue
  fi
  # a free slot
  while [ "$(jobs -rp | wc -l)" -ge "$jobs" ] && [ $stopping -eq 0 ]; do wait -n || true; done
  [ $stopping -eq 0 ] || break
  if [ -f "$dest/config.toml" ]; then
    echo "resume   $dest (at $done_rows/$epochs epochs)"
    cmd=(nice -n 19 "$apo" train --resume "$dest" --threads 1 ${quiet[@]+"${quiet[@]}"})
  else
    force=()
    if [ -d "$dest" ] && [ "$dry" != 1 ]; then
      # a run killed before it wrote its config.toml: start it again (--force removes only
      # what apo created there)
      rmdir "$dest" 2>/dev/null || force=(--force)
    fi
    [ "$dry" = 1 ] || mkdir -p "$(dirname "$dest")"
    echo "start    $dest (0/$epochs epochs)"
    cmd=(nice -n 19 "$apo" train --config "$run/config.toml" --out "$dest" --threads 1 ${quiet[@]+"${quiet[@]}"} ${force[@]+"${force[@]}"})
  fi
  if [ "$dry" = 1 ]; then echo "  (dry run) ${cmd[*]}"; continue; fi
  echo "== $(date '+%F %T') ${cmd[*]}" >>"$log"
  launch "$dest" "$log" "${cmd[@]}"
  started=$((started + 1))
done
# wait for the runs still going (a signal interrupts wait: the loop goes on until they end)
while [ -n "$(jobs -rp)" ]; do wait || true; done
failed=$(grep -c . "$failed_list" || true)
echo "started $started, skipped $skipped, failed $failed of ${#tasks[@]} runs"
if [ $stopping -gt 0 ]; then
  echo "interrupted: run the same command again to continue" >&2; exit 130
fi
[ "$failed" -eq 0 ]
