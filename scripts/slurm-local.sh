#!/usr/bin/env bash
# A real single-node Slurm cluster on this machine, from Debian's packages (slurm-wlm 22.05 and
# munge on bookworm), for tests and for trying Slurm on a laptop. Needs root; no systemd.
#
#   bash scripts/slurm-local.sh install   # apt-get install slurm-wlm munge (apt-get update first if missing)
#   bash scripts/slurm-local.sh start     # write the config, start munged, slurmctld, slurmd; wait until idle and a test step ran
#   bash scripts/slurm-local.sh status    # sinfo and squeue, or "not running"
#   bash scripts/slurm-local.sh stop      # stop the daemons this script started (by their pid files)
#   bash scripts/slurm-local.sh env       # print the `export SLURM_CONF=...` line
#
# Client commands (sbatch, srun, squeue, scontrol, scancel...) find the cluster through
#   export SLURM_CONF=${SLURM_LOCAL_DIR:-/tmp/apo-slurm}/slurm.conf
# which `start` prints; jobs get SLURM_CONF in their environment from slurmd. `start` also
# links /etc/slurm/slurm.conf (Debian's default place) to that file when /etc/slurm/slurm.conf
# is missing or is already such a link, so the commands work without the variable too.
#
# The cluster: one node named `hostname -s` at 127.0.0.1 with `nproc` CPUs and MemTotal minus a
# margin as RealMemory, one partition `debug` (default, no time limit), select/cons_tres with
# CR_Core (several 1-CPU jobs at once), no cgroups (proctrack/linuxproc, task/none: works in a
# container), no accounting (sacct has nothing to show: use squeue and `scontrol show job`),
# JobRequeue=1, MpiDefault=none (`srun --mpi=pmix` launches Debian's Open MPI programs; pmi2 does
# not), AuthInfo cred_expire=${SLURM_LOCAL_CRED_EXPIRE:-30} (a requeued job may start again after that
# many seconds; Slurm's default is 120). State, spool, pid files, logs and munged's socket live in
# ${SLURM_LOCAL_DIR:-/tmp/apo-slurm}; only the munge key is the system one
# (/etc/munge/munge.key, created if missing). Ports: slurmctld ${SLURM_LOCAL_CTLD_PORT:-6817},
# slurmd ${SLURM_LOCAL_SLURMD_PORT:-6818}, on 127.0.0.1.
# `stop` cancels the cluster's jobs (running and pending) before it stops the daemons, so that no
# job process outlives it; the state dir keeps job ids counting up (remove it after `stop` to
# start again from job 1).
set -euo pipefail

dir=${SLURM_LOCAL_DIR:-/tmp/apo-slurm}
conf=$dir/slurm.conf
ctld_port=${SLURM_LOCAL_CTLD_PORT:-6817}
slurmd_port=${SLURM_LOCAL_SLURMD_PORT:-6818}
wait_s=${SLURM_LOCAL_WAIT:-30}
# How long a step credential lives; also how long a requeued job waits before it may start again
# (Slurm's default is 120 s).
cred_expire=${SLURM_LOCAL_CRED_EXPIRE:-30}
munge_dir=$dir/munge
munge_socket=$munge_dir/munge.socket
munge_pid=$munge_dir/munged.pid
ctld_pid=$dir/slurmctld.pid
slurmd_pid=$dir/slurmd.pid
packages=(slurm-wlm munge)
export SLURM_CONF=$conf

die() {
  echo "slurm-local: error: $*" >&2
  exit 1
}

need_root() {
  [ "$(id -u)" -eq 0 ] || die "run as root (the daemons run as root, and munged as user munge)"
}

missing_packages() {
  local p
  for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || echo "$p"
  done
}

do_install() {
  need_root
  local missing
  missing=$(missing_packages)
  if [ -z "$missing" ]; then
    echo "slurm-local: slurm-wlm and munge are installed"
    return 0
  fi
  echo "slurm-local: installing ${packages[*]}"
  apt-get update
  DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends "${packages[@]}"
}

# The pid in FILE if that process is alive, else nothing (exit 1).
live_pid() {
  local pid
  [ -s "$1" ] || return 1
  pid=$(head -n1 "$1" 2>/dev/null | tr -dc 0-9)
  [ -n "$pid" ] && kill -0 "$pid" 2>/dev/null && echo "$pid"
}

any_running() {
  live_pid "$munge_pid" >/dev/null || live_pid "$ctld_pid" >/dev/null || live_pid "$slurmd_pid" >/dev/null
}

all_running() {
  live_pid "$munge_pid" >/dev/null && live_pid "$ctld_pid" >/dev/null && live_pid "$slurmd_pid" >/dev/null
}

# The node's state as sinfo says it ("idle", "mixed", "down*", "drained"...), or nothing.
node_state() {
  timeout 10 sinfo -h -N -n "$node" -o '%T' 2>/dev/null | head -n1
}

healthy() {
  all_running || return 1
  case "$(node_state)" in
    idle | mixed | allocated | completing) return 0 ;;
    *) return 1 ;;
  esac
}

node=$(hostname -s)

write_conf() {
  local cpus mem_mb margin
  cpus=$(nproc)
  mem_mb=$(awk '/^MemTotal:/ { print int($2 / 1024) }' /proc/meminfo)
  # slurmd drains a node that has less memory than RealMemory: leave 5% (at least 256 MB) out.
  margin=$((mem_mb / 20))
  [ "$margin" -ge 256 ] || margin=256
  mem_mb=$((mem_mb - margin))
  [ "$mem_mb" -ge 1 ] || mem_mb=1
  mkdir -p "$dir/state" "$dir/spool"
  cat >"$conf.tmp" <<EOF
# Written by scripts/slurm-local.sh: a single-node Slurm cluster on localhost.
ClusterName=apo-local
SlurmctldHost=$node(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$munge_socket,cred_expire=$cred_expire
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$ctld_pid
SlurmdPidFile=$slurmd_pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
SwitchType=switch/none
ReturnToService=2
JobRequeue=1
MailProg=/bin/true
# Finished jobs stay visible to scontrol/squeue for this many seconds.
MinJobAge=300
KillWait=30
NodeName=$node NodeAddr=127.0.0.1 NodeHostname=$node CPUs=$cpus RealMemory=$mem_mb State=UNKNOWN
PartitionName=debug Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF
  mv "$conf.tmp" "$conf"
  # Debian's client commands read /etc/slurm/slurm.conf when SLURM_CONF is not set.
  mkdir -p /etc/slurm
  if [ ! -e /etc/slurm/slurm.conf ] && [ ! -L /etc/slurm/slurm.conf ]; then
    ln -s "$conf" /etc/slurm/slurm.conf
  elif [ -L /etc/slurm/slurm.conf ]; then
    ln -sfn "$conf" /etc/slurm/slurm.conf
  fi
}

start_munged() {
  if live_pid "$munge_pid" >/dev/null; then
    return 0
  fi
  id munge >/dev/null 2>&1 || die "no user munge: run '$0 install' first"
  if [ ! -s /etc/munge/munge.key ]; then
    echo "slurm-local: creating /etc/munge/munge.key"
    install -d -o munge -g munge -m 0700 /etc/munge
    if command -v mungekey >/dev/null; then
      mungekey --create --keyfile=/etc/munge/munge.key --force
    else
      dd if=/dev/urandom of=/etc/munge/munge.key bs=1 count=1024 status=none
    fi
  fi
  chown munge:munge /etc/munge /etc/munge/munge.key
  chmod 0700 /etc/munge
  chmod 0400 /etc/munge/munge.key
  # munged wants its socket's folder owned by its user and not writable by others.
  chmod 0755 "$dir"
  install -d -o munge -g munge -m 0755 "$munge_dir"
  rm -f "$munge_socket" "$munge_socket.lock" "$munge_pid"
  runuser -u munge -- munged --socket="$munge_socket" --pid-file="$munge_pid" \
    --log-file="$munge_dir/munged.log" --seed-file="$munge_dir/munged.seed" \
    --key-file=/etc/munge/munge.key ||
    die "munged did not start; its log:$(echo; tail -n 20 "$munge_dir/munged.log" 2>/dev/null)"
  for _ in $(seq 50); do
    [ -S "$munge_socket" ] && live_pid "$munge_pid" >/dev/null && break
    sleep 0.1
  done
  munge -n --socket="$munge_socket" | unmunge --socket="$munge_socket" >/dev/null ||
    die "munge does not work; munged's log:$(echo; tail -n 20 "$munge_dir/munged.log" 2>/dev/null)"
}

show_logs() {
  local f
  for f in "$munge_dir/munged.log" "$dir/slurmctld.log" "$dir/slurmd.log"; do
    [ -f "$f" ] || continue
    echo "---- tail of $f" >&2
    tail -n 20 "$f" >&2
  done
}

print_env() {
  echo "export SLURM_CONF=$conf"
}

start() {
  need_root
  [ -z "$(missing_packages)" ] || die "slurm-wlm or munge is missing: run '$0 install' first"
  if healthy; then
    echo "slurm-local: already running (node $node $(node_state))"
    print_env
    return 0
  fi
  if any_running; then
    echo "slurm-local: partly running or unhealthy: restarting"
    stop
  fi
  local t0=$SECONDS port
  for port in "$ctld_port" "$slurmd_port"; do
    if (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null; then
      die "port $port on 127.0.0.1 is taken (another slurmctld/slurmd?); stop it, or set SLURM_LOCAL_CTLD_PORT / SLURM_LOCAL_SLURMD_PORT"
    fi
  done
  mkdir -p "$dir"
  write_conf
  start_munged
  rm -f "$ctld_pid" "$slurmd_pid"
  slurmctld -f "$conf" || {
    show_logs
    die "slurmctld did not start"
  }
  slurmd -f "$conf" || {
    show_logs
    die "slurmd did not start"
  }
  local state="" deadline=$((SECONDS + wait_s))
  while [ "$SECONDS" -lt "$deadline" ]; do
    state=$(node_state)
    case "$state" in
      idle | mixed | allocated) break ;;
    esac
    sleep 0.5
  done
  case "$state" in
    idle | mixed | allocated) ;;
    *)
      timeout 10 sinfo -R >&2 2>/dev/null || true
      show_logs
      die "node $node is not up after ${wait_s}s (state: '${state:-no answer}'); '$0 stop' stops what started"
      ;;
  esac
  # End to end: munge, slurmctld, slurmd and slurmstepd all take part in a one-task step.
  local out
  if ! out=$(timeout "$wait_s" srun -N1 -n1 -t 1 -J slurm-local-check hostname 2>&1); then
    echo "$out" >&2
    show_logs
    die "a test step (srun hostname) did not run within ${wait_s}s; '$0 stop' stops what started"
  fi
  echo "slurm-local: started in $((SECONDS - t0))s: node $node ($state), partition debug; a test step ran; state in $dir"
  print_env
}

# Sends TERM to the process in FILE and waits (up to 30 s, then KILL) until it is gone.
stop_one() {
  local name=$1 file=$2 pid
  pid=$(live_pid "$file") || {
    rm -f "$file"
    return 0
  }
  kill -TERM "$pid" 2>/dev/null || true
  for _ in $(seq 300); do
    kill -0 "$pid" 2>/dev/null || break
    sleep 0.1
  done
  if kill -0 "$pid" 2>/dev/null; then
    echo "slurm-local: $name ($pid) still there after 30 s: KILL" >&2
    kill -KILL "$pid" 2>/dev/null || true
    sleep 0.5
  fi
  rm -f "$file"
  echo "slurm-local: stopped $name ($pid)"
}

# slurmstepd processes of this cluster (they carry its SLURM_CONF in their environment).
our_stepds() {
  local p
  for p in $(pgrep -x slurmstepd 2>/dev/null || true); do
    tr '\0' '\n' <"/proc/$p/environ" 2>/dev/null | grep -qxF "SLURM_CONF=$conf" && echo "$p"
  done
  return 0
}

stop() {
  need_root
  if ! any_running && [ -z "$(our_stepds)" ]; then
    echo "slurm-local: not running"
    return 0
  fi
  local jobs p
  if all_running && jobs=$(timeout 10 squeue -h -o %i 2>/dev/null) && [ -n "$jobs" ]; then
    echo "slurm-local: cancelling jobs: $(echo "$jobs" | tr '\n' ' ')"
    timeout 10 scancel --partition=debug || true
    # Jobs get SIGTERM, then SIGKILL after KillWait (30 s).
    for _ in $(seq 90); do
      [ -n "$(timeout 10 squeue -h -o %i 2>/dev/null)" ] || break
      sleep 0.5
    done
  fi
  stop_one slurmd "$slurmd_pid"
  stop_one slurmctld "$ctld_pid"
  stop_one munged "$munge_pid"
  for p in $(our_stepds); do
    echo "slurm-local: killing a leftover slurmstepd ($p) and its processes" >&2
    pkill -KILL -P "$p" 2>/dev/null || true
    kill -KILL "$p" 2>/dev/null || true
  done
}

status() {
  if ! any_running; then
    echo "slurm-local: not running"
    return 0
  fi
  local name file
  for name in munged slurmctld slurmd; do
    case $name in
      munged) file=$munge_pid ;;
      slurmctld) file=$ctld_pid ;;
      slurmd) file=$slurmd_pid ;;
    esac
    if pid=$(live_pid "$file"); then
      echo "$name: running ($pid)"
    else
      echo "$name: not running"
    fi
  done
  print_env
  timeout 10 sinfo || true
  timeout 10 squeue || true
}

case "${1:-}" in
  install) do_install ;;
  start) start ;;
  stop) stop ;;
  status) status ;;
  env) print_env ;;
  *)
    sed -n '2,/^set -euo/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'
    exit 2
    ;;
esac
