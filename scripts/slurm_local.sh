#!/usr/bin/env bash
# A single-node Slurm cluster entirely under one folder, for the tests of the Slurm
# executor (tune/slurm_executor.h) and for trying `echoservo tune --slurm` on one machine
# (docs/tuning_slurm.md). Debian's slurm-wlm (22.05) + munge; scripts/setup.sh installs them.
#
#   scripts/slurm_local.sh start DIR   munged, slurmctld and slurmd with every file under DIR
#                                      (munge key and socket, slurm.conf, state, spool, logs,
#                                      pid files); returns once `sinfo` shows the node idle
#                                      and an empty check job has run
#   scripts/slurm_local.sh env DIR     prints `export SLURM_CONF=DIR/slurm.conf`
#   scripts/slurm_local.sh stop DIR    cancels every job, stops the daemons and whatever they
#                                      started (no process is left behind); idempotent
#   scripts/slurm_local.sh status DIR  exit status 0 when the node answers
#
# The cluster: this host (`hostname -s`, at 127.0.0.1) with its real CPUs and memory
# (`slurmd -C`), one partition "debug", controller and node on free TCP ports, munge
# authentication through DIR/munge.socket (the system munge is not used), no accounting
# (`sacct` is unavailable: callers fall back to `scontrol show job`), MinJobAge=5 s (so
# that `sbatch --wait` polls every 2 s).
# Exit status of start: 0 when the node is idle and runs jobs; 77 when this machine cannot run it (not
# root, binaries missing), with the reason on stderr and in DIR/skip_reason; 1 when the
# daemons did not come up, with their logs' tails on stderr (and the daemons stopped).
# ECHOSERVO_SLURM_START_TIMEOUT_S (20) bounds the wait for the idle node.
# ECHOSERVO_SLURM_OVERSUBSCRIBE=N lets N jobs share each core (OverSubscribe=FORCE:N): the
# tests' fake trials sleep, so they all start in one scheduling pass.
# ECHOSERVO_SLURM_SKIP_OK=1: start exits 0 where it would exit 77 or 1 (DIR/skip_reason says
# why), for a CTest fixture whose tests then skip with that reason.
set -euo pipefail

usage() {
  echo "usage: scripts/slurm_local.sh start|stop|env|status DIR" >&2
  exit 2
}
[[ $# -eq 2 ]] || usage
action=$1
dir=$2
[[ -n "$dir" ]] || usage
case "$action" in start | stop | env | status) ;; *) usage ;; esac

if [[ "$action" == start ]]; then
  mkdir -p "$dir"
fi
if [[ -d "$dir" ]]; then
  dir=$(cd "$dir" && pwd -P)
fi
conf="$dir/slurm.conf"
# Every daemon is started with this in its environment, which its children (slurmstepd, the
# batch scripts) inherit: `stop` ends exactly the processes that carry it.
marker="ECHOSERVO_SLURM_LOCAL=$dir"

skip() {
  echo "slurm_local: cannot start a local Slurm here: $*" >&2
  echo "$*" >"$dir/skip_reason"
  [[ "${ECHOSERVO_SLURM_SKIP_OK:-0}" == 1 ]] && exit 0
  exit 77
}

# Pids of the processes that carry this cluster's marker in their environment.
marked_pids() {
  grep -lszxF "$marker" /proc/[0-9]*/environ 2>/dev/null | sed -E 's|^/proc/([0-9]+)/environ$|\1|' || true
}

stop_cluster() {
  if [[ -f "$conf" ]] && [[ -f "$dir/slurmctld.pid" ]]; then
    # Cancel jobs first so that slurmstepd ends its tasks itself.
    SLURM_CONF="$conf" timeout 5 scancel --quiet --full --user="$(id -un)" 2>/dev/null || true
  fi
  local f pid
  for f in slurmd slurmctld munged; do
    if [[ -f "$dir/$f.pid" ]]; then
      pid=$(cat "$dir/$f.pid" 2>/dev/null || true)
      if [[ "$pid" =~ ^[0-9]+$ ]]; then
        kill -TERM "$pid" 2>/dev/null || true
      fi
    fi
  done
  # Whatever carries the marker (daemons, slurmstepd, job scripts): TERM, then KILL.
  local i left
  for i in $(seq 1 50); do
    left=$(marked_pids)
    [[ -z "$left" ]] && break
    if [[ $i -eq 1 ]] || [[ $i -eq 25 ]]; then
      # shellcheck disable=SC2086
      kill -TERM $left 2>/dev/null || true
    fi
    if [[ $i -ge 40 ]]; then
      # shellcheck disable=SC2086
      kill -KILL $left 2>/dev/null || true
    fi
    sleep 0.1
  done
  rm -f "$dir/slurmd.pid" "$dir/slurmctld.pid" "$dir/munged.pid"
  left=$(marked_pids)
  if [[ -n "$left" ]]; then
    echo "slurm_local: processes still running after stop: $left" >&2
    return 1
  fi
}

log_tails() {
  local f
  for f in munged.log slurmctld.log slurmd.log; do
    if [[ -f "$dir/$f" ]]; then
      echo "---- $dir/$f (last 15 lines)" >&2
      tail -n 15 "$dir/$f" >&2
    fi
  done
}

fail_start() {
  echo "slurm_local: the cluster did not start: $*" >&2
  log_tails
  stop_cluster || true
  echo "the local Slurm did not start: $* (daemon logs in $dir)" >"$dir/skip_reason"
  [[ "${ECHOSERVO_SLURM_SKIP_OK:-0}" == 1 ]] && exit 0
  exit 1
}

# A TCP port that nothing listens on (from /proc/net/tcp{,6}; no extra tools).
used_ports() {
  cat /proc/net/tcp /proc/net/tcp6 2>/dev/null | awk 'NR > 1 { split($2, a, ":"); print a[2] }'
}
free_port() {
  local avoid=${1:-} used port hex
  used=$(used_ports)
  for _ in $(seq 1 200); do
    port=$((20000 + RANDOM % 40000))
    [[ "$port" == "$avoid" ]] && continue
    hex=$(printf '%04X' "$port")
    if ! grep -qx "$hex" <<<"$used"; then
      echo "$port"
      return 0
    fi
  done
  return 1
}

case "$action" in
env)
  echo "export SLURM_CONF=$conf"
  exit 0
  ;;
status)
  [[ -f "$conf" ]] || exit 1
  SLURM_CONF="$conf" timeout 5 sinfo -h -N -o %t 2>/dev/null | grep -qE '^(idle|mix|alloc)' || exit 1
  exit 0
  ;;
stop)
  [[ -d "$dir" ]] || exit 0
  stop_cluster
  exit $?
  ;;
esac

# ---- start
rm -f "$dir/skip_reason"
if [[ $(id -u) -ne 0 ]]; then
  skip "needs root (SlurmUser=root, slurmd runs jobs as their user); running as $(id -un)"
fi
for b in munged slurmctld slurmd sbatch sinfo scontrol scancel timeout; do
  if ! command -v "$b" >/dev/null 2>&1 && [[ ! -x "/usr/sbin/$b" ]]; then
    skip "$b is not installed (Debian: apt-get install slurm-wlm munge)"
  fi
done
export PATH="$PATH:/usr/sbin"
if [[ -f "$dir/slurmctld.pid" ]] && "$0" status "$dir" 2>/dev/null; then
  echo "slurm_local: already running in $dir" >&2
  exit 0
fi
stop_cluster 2>/dev/null || true

host=$(hostname -s)
[[ -n "$host" ]] || skip "hostname -s gives no name"
chmod 700 "$dir"
mkdir -p "$dir/state" "$dir/spool"
rm -rf "${dir:?}/state/"* "${dir:?}/spool/"*

# munge: a key of its own, every file under DIR.
if [[ ! -s "$dir/munge.key" ]]; then
  if command -v mungekey >/dev/null 2>&1 || [[ -x /usr/sbin/mungekey ]]; then
    PATH="$PATH:/usr/sbin" mungekey --create --force --keyfile="$dir/munge.key" 2>/dev/null ||
      dd if=/dev/urandom of="$dir/munge.key" bs=1024 count=1 status=none
  else
    dd if=/dev/urandom of="$dir/munge.key" bs=1024 count=1 status=none
  fi
fi
chmod 400 "$dir/munge.key"
env "$marker" munged --force --socket="$dir/munge.socket" --key-file="$dir/munge.key" \
  --pid-file="$dir/munged.pid" --log-file="$dir/munged.log" --seed-file="$dir/munged.seed" \
  2>>"$dir/munged.log" || fail_start "munged exited with status $?"

# slurm.conf: this node's real CPUs and memory.
node_line=$(slurmd -C 2>/dev/null | head -n 1) || true
[[ "$node_line" == NodeName=* ]] || fail_start "slurmd -C printed no node line: $node_line"
node_line=$(sed -E "s/^NodeName=[^ ]+/NodeName=$host NodeAddr=127.0.0.1/" <<<"$node_line")
ctld_port=$(free_port) || fail_start "no free TCP port"
slurmd_port=$(free_port "$ctld_port") || fail_start "no free TCP port"
oversubscribe=""
if [[ -n "${ECHOSERVO_SLURM_OVERSUBSCRIBE:-}" ]]; then
  [[ "$ECHOSERVO_SLURM_OVERSUBSCRIBE" =~ ^[0-9]+$ ]] ||
    fail_start "ECHOSERVO_SLURM_OVERSUBSCRIBE must be a count, not '$ECHOSERVO_SLURM_OVERSUBSCRIBE'"
  oversubscribe=" OverSubscribe=FORCE:$ECHOSERVO_SLURM_OVERSUBSCRIBE"
fi
cat >"$conf" <<EOF
# Written by scripts/slurm_local.sh: a single-node test cluster under $dir.
ClusterName=echoservo
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$dir/munge.socket
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SwitchType=switch/none
MpiDefault=none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/builtin
SchedulerParameters=batch_sched_delay=0,sched_min_interval=0
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/none
MailProg=/bin/true
ReturnToService=2
MinJobAge=5
KillWait=5
InactiveLimit=0
$node_line State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP$oversubscribe
EOF
: >"$dir/slurmctld.log"
: >"$dir/slurmd.log"

export SLURM_CONF="$conf"
env "$marker" slurmctld -f "$conf" -i || fail_start "slurmctld exited with status $?"
env "$marker" slurmd -f "$conf" || fail_start "slurmd exited with status $?"

deadline=$((SECONDS + ${ECHOSERVO_SLURM_START_TIMEOUT_S:-20}))
state=""
while ((SECONDS < deadline)); do
  state=$(timeout 5 sinfo -h -N -o %t 2>/dev/null | head -n 1 || true)
  if [[ "$state" == idle ]]; then
    break
  fi
  if [[ "$state" == down* ]] || [[ "$state" == drain* ]]; then
    timeout 5 scontrol update NodeName="$host" State=RESUME 2>/dev/null || true
  fi
  sleep 0.2
done
[[ "$state" == idle ]] ||
  fail_start "the node is not idle after ${ECHOSERVO_SLURM_START_TIMEOUT_S:-20} s (sinfo: '${state:-no answer}')"

# One empty job, run to its end: the cluster runs jobs (the controller schedules its first
# about 3 s after it starts, which this wait takes instead of the first real job).
job=$(timeout 10 sbatch --parsable --output=/dev/null --chdir="$dir" --job-name=slurm_local-check \
  --wrap=true 2>&1) || fail_start "sbatch refused a check job: $job"
while ((SECONDS < deadline)); do
  queued=$(timeout 5 squeue --noheader --jobs="$job" --format=%i 2>/dev/null) || queued=unknown
  if [[ -z "$queued" ]]; then
    echo "slurm_local: node $host idle, a job ran (controller port $ctld_port, slurmd port" \
      "$slurmd_port)" >&2
    exit 0
  fi
  sleep 0.1
done
fail_start "the check job $job did not run within ${ECHOSERVO_SLURM_START_TIMEOUT_S:-20} s"
