#!/usr/bin/env bash
# A one-node SLURM cluster on this machine (Debian's slurm-wlm + munge), for trying `--executor slurm`.
#
#   apt-get install -y slurm-wlm munge        # once, as root
#   benchmarks/slurm_local_cluster.sh start   # munged + slurmctld + slurmd; partition "cpu" = this host
#   benchmarks/slurm_local_cluster.sh status  # sinfo
#   benchmarks/slurm_local_cluster.sh stop
#
# Needs root (SlurmUser=root, no cgroups: ProctrackType=proctrack/linuxproc, TaskPlugin=task/none).
# State and logs live under $SLURM_LOCAL_DIR (default /tmp/slurm_local).
set -euo pipefail

DIR=${SLURM_LOCAL_DIR:-/tmp/slurm_local}
CONF=/etc/slurm/slurm.conf
HOST=$(hostname -s)
CPUS=$(env -u OMP_NUM_THREADS -u OMP_THREAD_LIMIT nproc)  # nproc alone honours OMP_NUM_THREADS, which the tests set to 1
MEM_MB=$(awk '/MemTotal/ {print int($2 / 1024 * 0.9)}' /proc/meminfo)

start() {
  command -v slurmctld >/dev/null && command -v munged >/dev/null || {
    echo "slurm-wlm / munge not installed: apt-get install -y slurm-wlm munge" >&2
    exit 1
  }
  mkdir -p "$DIR"/{state,spool,log} /etc/slurm /run/munge /var/log/munge /var/lib/munge
  chown -R munge:munge /run/munge /var/log/munge /var/lib/munge /etc/munge
  [ -s /etc/munge/munge.key ] || mungekey --create --force
  chown munge:munge /etc/munge/munge.key && chmod 400 /etc/munge/munge.key
  pgrep -x munged >/dev/null || su -s /bin/sh munge -c "munged --force"
  cat >"$CONF" <<EOF
ClusterName=local
SlurmctldHost=$HOST
SlurmUser=root
AuthType=auth/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
SchedulerType=sched/backfill
ReturnToService=2
StateSaveLocation=$DIR/state
SlurmdSpoolDir=$DIR/spool
SlurmctldLogFile=$DIR/log/slurmctld.log
SlurmdLogFile=$DIR/log/slurmd.log
SlurmctldPidFile=$DIR/slurmctld.pid
SlurmdPidFile=$DIR/slurmd.pid
MpiDefault=none
JobAcctGatherType=jobacct_gather/none
NodeName=$HOST CPUs=$CPUS RealMemory=$MEM_MB State=UNKNOWN
PartitionName=cpu Nodes=$HOST Default=YES MaxTime=INFINITE State=UP
EOF
  pgrep -x slurmctld >/dev/null || slurmctld
  pgrep -x slurmd >/dev/null || slurmd
  for _ in $(seq 1 60); do
    if sinfo -h -o %T 2>/dev/null | grep -qE "idle|mix|alloc"; then
      sinfo
      return 0
    fi
    sleep 0.5
  done
  echo "slurm did not come up; see $DIR/log" >&2
  exit 1
}

stop() {
  for d in slurmd slurmctld; do
    [ -f "$DIR/$d.pid" ] && kill "$(cat "$DIR/$d.pid")" 2>/dev/null || true
  done
  for _ in $(seq 1 40); do  # gone before returning, so that a start right after starts them again
    pgrep -x slurmctld >/dev/null || pgrep -x slurmd >/dev/null || return 0
    sleep 0.25
  done
}

case "${1:-start}" in
  start) start ;;
  stop) stop ;;
  status) sinfo ;;
  *) echo "usage: $0 start|stop|status" >&2; exit 2 ;;
esac
