#!/usr/bin/env bash
# A real single-node Slurm on this machine, for the farm tests (and for trying
# `theia farm` by hand).
#
#   tools/slurm-local.sh install   apt-get slurm-wlm and munge (skipped when present)
#   tools/slurm-local.sh start     write the config under $SLURM_LOCAL_DIR, start munged, slurmctld, slurmd
#   tools/slurm-local.sh stop      stop the daemons this script started
#   tools/slurm-local.sh env       print the `export SLURM_CONF=...` line that points the clients at it
#
# The node is localhost with this machine's cores and memory; partitions:
# `debug` (the default) and `preempt`.  Everything (config, state, logs, pid
# files, munge socket) lives in $SLURM_LOCAL_DIR (default /tmp/theia-slurm), so
# it touches no system configuration and several copies cannot collide as
# long as they use different directories and ports ($SLURM_LOCAL_PORT, default
# 6917, and the next one for slurmd).  Exit 2 from start: the daemons cannot
# run here (the message says why).
set -euo pipefail

DIR=${SLURM_LOCAL_DIR:-/tmp/theia-slurm}
PORT=${SLURM_LOCAL_PORT:-6917}
CONF=$DIR/slurm.conf

need_root() {
  if [ "$(id -u)" -ne 0 ]; then
    echo "slurm-local: must run as root (slurmd runs jobs as their user)" >&2
    exit 2
  fi
}

install() {
  local missing=()
  for p in slurm-wlm munge; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  need_root
  echo "slurm-local: installing ${missing[*]}"
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}"
}

write_config() {
  mkdir -p "$DIR"/{state,spool,log,munge,run}
  local cpus mem_mb
  cpus=$(nproc)
  mem_mb=$(awk '/MemTotal/ { printf "%d", $2 / 1024 * 0.9 }' /proc/meminfo)
  # munge: a key of our own, its socket and state in $DIR.
  if [ ! -s "$DIR/munge/munge.key" ]; then
    dd if=/dev/urandom of="$DIR/munge/munge.key" bs=1024 count=1 status=none
  fi
  chmod 700 "$DIR/munge"
  chmod 400 "$DIR/munge/munge.key"
  cat >"$CONF" <<CONF
ClusterName=theia-local
SlurmctldHost=localhost
SlurmctldPort=$PORT
SlurmdPort=$((PORT + 1))
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$DIR/munge/munge.socket
StateSaveLocation=$DIR/state
SlurmdSpoolDir=$DIR/spool
SlurmctldPidFile=$DIR/run/slurmctld.pid
SlurmdPidFile=$DIR/run/slurmd.pid
SlurmctldLogFile=$DIR/log/slurmctld.log
SlurmdLogFile=$DIR/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MpiDefault=none
ReturnToService=2
SwitchType=switch/none
# A preempted or timed-out task gets SIGTERM (plus --signal's warning) and
# KillWait seconds before SIGKILL.
KillWait=20
MinJobAge=600
SchedulerParameters=bf_interval=1
SlurmctldParameters=enable_configless
SlurmctldTimeout=30
SlurmdTimeout=30
NodeName=localhost CPUs=$cpus RealMemory=$mem_mb State=UNKNOWN
PartitionName=debug Nodes=localhost Default=YES MaxTime=INFINITE State=UP OverSubscribe=NO
PartitionName=preempt Nodes=localhost MaxTime=INFINITE State=UP PriorityTier=1 PreemptMode=REQUEUE
CONF
  # slurmctld runs a job's epilog etc. nowhere; cgroup.conf is not needed with task/none.
}

wait_for() {  # wait_for SECONDS COMMAND...: poll until COMMAND succeeds
  local t=$1
  shift
  for _ in $(seq 1 $((t * 4))); do
    "$@" >/dev/null 2>&1 && return 0
    sleep 0.25
  done
  return 1
}

start() {
  need_root
  for b in munged slurmctld slurmd sinfo; do
    command -v "$b" >/dev/null || { echo "slurm-local: $b not found (run: $0 install)" >&2; exit 2; }
  done
  write_config
  export SLURM_CONF=$CONF
  munged --socket="$DIR/munge/munge.socket" --key-file="$DIR/munge/munge.key" \
    --pid-file="$DIR/run/munged.pid" --log-file="$DIR/log/munged.log" --seed-file="$DIR/munge/munge.seed" \
    --force 2>"$DIR/log/munged.err" || { echo "slurm-local: munged did not start: $(cat "$DIR/log/munged.err")" >&2; exit 2; }
  slurmctld -f "$CONF" 2>"$DIR/log/slurmctld.err" || {
    echo "slurm-local: slurmctld did not start: $(tail -3 "$DIR/log/slurmctld.err" "$DIR/log/slurmctld.log" 2>/dev/null)" >&2
    exit 2
  }
  slurmd -f "$CONF" 2>"$DIR/log/slurmd.err" || {
    echo "slurm-local: slurmd did not start: $(tail -3 "$DIR/log/slurmd.err" "$DIR/log/slurmd.log" 2>/dev/null)" >&2
    exit 2
  }
  if ! wait_for 30 bash -c "sinfo -h -N -o '%T' | grep -Eq '^(idle|mixed|allocated)'"; then
    echo "slurm-local: the node did not become idle in 30 s: $(sinfo -N 2>&1 | tail -1); slurmd log: $(tail -3 "$DIR/log/slurmd.log" 2>/dev/null)" >&2
    stop
    exit 2
  fi
  echo "slurm-local: up ($(sinfo -h -N -o '%N %c CPUs %T' | sort -u | paste -sd ' '))"
}

kill_pidfile() {
  local f=$1
  [ -s "$f" ] || return 0
  local pid
  pid=$(cat "$f")
  if kill "$pid" 2>/dev/null; then
    for _ in $(seq 1 40); do kill -0 "$pid" 2>/dev/null || break; sleep 0.25; done
    kill -9 "$pid" 2>/dev/null || true
  fi
  rm -f "$f"
}

stop() {
  export SLURM_CONF=$CONF
  [ -f "$CONF" ] && scancel --full --user="$(id -un)" >/dev/null 2>&1 || true
  kill_pidfile "$DIR/run/slurmd.pid"
  kill_pidfile "$DIR/run/slurmctld.pid"
  kill_pidfile "$DIR/run/munged.pid"
}

case "${1:-}" in
  install) install ;;
  start) start ;;
  stop) stop ;;
  env) echo "export SLURM_CONF=$CONF" ;;
  *) echo "usage: $0 install|start|stop|env" >&2; exit 64 ;;
esac
