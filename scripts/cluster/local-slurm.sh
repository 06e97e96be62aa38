#!/usr/bin/env bash
# A single-node Slurm cluster in a folder of its own, for tests and for trying the
# cluster scripts on one machine: Debian's slurmctld, slurmd and munge, run as root.
#   scripts/cluster/local-slurm.sh start DIR   configure in DIR, start munged, slurmctld
#                                              and slurmd, wait for the node; prints
#                                              `export SLURM_CONF=DIR/slurm.conf`
#   scripts/cluster/local-slurm.sh stop DIR    stop the three daemons started in DIR
# A daemon that does not start fails the script and prints its log.
set -euo pipefail

cmd=${1:?usage: local-slurm.sh start|stop DIR}
dir=${2:?usage: local-slurm.sh start|stop DIR}

stop() {
  for d in slurmd slurmctld munged; do
    if [[ -f "$dir/$d.pid" ]]; then
      kill "$(cat "$dir/$d.pid")" 2>/dev/null || true
    fi
  done
  for d in slurmd slurmctld munged; do
    if [[ -f "$dir/$d.pid" ]]; then
      pid=$(cat "$dir/$d.pid")
      for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
      kill -9 "$pid" 2>/dev/null || true
      rm -f "$dir/$d.pid"
    fi
  done
}

fail() {
  echo "local-slurm: $1" >&2
  for log in "$dir"/munged.log "$dir"/slurmctld.log "$dir"/slurmd.log; do
    [[ -f "$log" ]] && { echo "---- $log" >&2; tail -n 40 "$log" >&2; }
  done
  stop
  exit 1
}

if [[ "$cmd" == stop ]]; then
  stop
  exit 0
fi
[[ "$cmd" == start ]] || { echo "usage: local-slurm.sh start|stop DIR" >&2; exit 2; }
for b in munged slurmctld slurmd sinfo; do
  command -v "$b" >/dev/null || { echo "local-slurm: $b is missing: expected Debian's munge, slurmctld, slurmd and slurm-client (scripts/deps.sh --cluster)" >&2; exit 1; }
done
[[ $(id -u) -eq 0 ]] || { echo "local-slurm: the daemons run as root here" >&2; exit 1; }

dir=$(mkdir -p "$dir" && cd "$dir" && pwd)
chmod 700 "$dir"
mkdir -p "$dir/state" "$dir/spool"
host=$(hostname -s)
# Ports of this cluster's own, away from a system Slurm's 6817/6818.
base=$(( 20000 + RANDOM % 20000 ))

# munge: a key of our own, its socket in DIR.
dd if=/dev/urandom bs=1 count=1024 of="$dir/munge.key" status=none
chmod 400 "$dir/munge.key"
munged --key-file="$dir/munge.key" --socket="$dir/munge.sock" \
  --pid-file="$dir/munged.pid" --log-file="$dir/munged.log" \
  --seed-file="$dir/munged.seed" --force || fail "munged did not start"

node=$(slurmd -C | head -n 1)
cat > "$dir/slurm.conf" <<CONF
ClusterName=palpa
SlurmctldHost=$host
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$dir/munge.sock
SlurmctldPort=$base
SlurmdPort=$(( base + 1 ))
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
MpiDefault=none
$node State=UNKNOWN
PartitionName=palpa Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF="$dir/slurm.conf"
slurmctld -f "$SLURM_CONF" || fail "slurmctld did not start"
slurmd -f "$SLURM_CONF" || fail "slurmd did not start"
for _ in $(seq 100); do
  state=$(sinfo -h -N -o %t 2>/dev/null | head -n 1 || true)
  [[ "$state" == idle* ]] && { echo "export SLURM_CONF=$SLURM_CONF"; exit 0; }
  sleep 0.2
done
fail "the node did not come up idle (sinfo: ${state:-nothing})"
