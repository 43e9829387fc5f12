#!/usr/bin/env bash
# A one-node SLURM cluster on this machine, for tests and for trying
# `red-cli mujoco table --slurm` before a real cluster:
#
#   scripts/slurm-local.sh start    install slurm-wlm and munge from Debian's
#                                   packages if missing (apt-get; needs root),
#                                   write a one-node slurm.conf for localhost
#                                   (CPUs as `nproc` says), start munged,
#                                   slurmctld and slurmd, wait for the node
#   scripts/slurm-local.sh stop     stop the daemons this script started and
#                                   remove the slurm.conf it wrote
#   scripts/slurm-local.sh status   exit 0 if the node answers and takes jobs
#
# Idempotent: `start` leaves running daemons alone, `stop` stops only what
# `start` started (their pids are kept in the state folder). Made for a
# container: process tracking by process tree (proctrack/linuxproc), no task
# plugin, no cgroups, no accounting, everything runs as root.
#
# The state folder (spool, logs, pid files) is $RED_SLURM_DIR, default
# /var/tmp/red-slurm. The configuration goes to /etc/slurm/slurm.conf (where
# sbatch, squeue and scancel look) unless a slurm.conf that this script did
# not write is there: then `start` stops with a message.
set -euo pipefail

STATE="${RED_SLURM_DIR:-/var/tmp/red-slurm}"
CONF=/etc/slurm/slurm.conf
MARK="# written by red scripts/slurm-local.sh"
HOST="$(hostname -s)"

die() { echo "slurm-local: $*" >&2; exit 1; }
note() { echo "slurm-local: $*" >&2; }

as_root() {
    if [ "$(id -u)" -eq 0 ]; then "$@"
    elif command -v sudo >/dev/null; then sudo "$@"
    else die "needs root (or sudo) for: $*"; fi
}

alive() { [ -f "$1" ] && kill -0 "$(cat "$1")" 2>/dev/null; }

install_packages() {
    if command -v slurmctld >/dev/null && command -v slurmd >/dev/null \
        && command -v sbatch >/dev/null && command -v munged >/dev/null; then
        return
    fi
    note "installing slurm-wlm and munge (apt-get)"
    export DEBIAN_FRONTEND=noninteractive
    as_root apt-get install -y -q --no-install-recommends slurm-wlm munge >/dev/null \
        || { as_root apt-get update -q >/dev/null \
             && as_root apt-get install -y -q --no-install-recommends slurm-wlm munge >/dev/null; } \
        || die "apt-get could not install slurm-wlm and munge"
    command -v slurmctld >/dev/null || die "slurmctld missing after installing slurm-wlm"
}

start_munge() {
    if munge -n 2>/dev/null | unmunge >/dev/null 2>&1; then
        return
    fi
    if [ ! -s /etc/munge/munge.key ]; then
        as_root mkdir -p /etc/munge
        as_root dd if=/dev/urandom of=/etc/munge/munge.key bs=128 count=1 status=none
        as_root chown munge:munge /etc/munge/munge.key
        as_root chmod 400 /etc/munge/munge.key
    fi
    as_root mkdir -p /run/munge /var/log/munge /var/lib/munge
    as_root chown munge:munge /run/munge /var/log/munge /var/lib/munge
    as_root runuser -u munge -- /usr/sbin/munged
    for _ in $(seq 50); do
        if munge -n 2>/dev/null | unmunge >/dev/null 2>&1; then
            cp /run/munge/munged.pid "$STATE/munged.pid"
            return
        fi
        sleep 0.1
    done
    die "munged did not start (see /var/log/munge/munged.log)"
}

write_conf() {
    if [ -e "$CONF" ] && ! grep -qF "$MARK" "$CONF"; then
        die "$CONF exists and was not written by this script; leaving it alone"
    fi
    local cpus mem_mb
    cpus="$(nproc)"
    mem_mb="$(awk '/MemTotal/ { printf "%d", $2 / 1024 * 0.9 }' /proc/meminfo)"
    as_root mkdir -p /etc/slurm
    as_root tee "$CONF" >/dev/null <<EOF
$MARK
ClusterName=red-local
SlurmctldHost=$HOST(127.0.0.1)
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
StateSaveLocation=$STATE/ctld
SlurmdSpoolDir=$STATE/d
SlurmctldPidFile=$STATE/slurmctld.pid
SlurmdPidFile=$STATE/slurmd.pid
SlurmctldLogFile=$STATE/slurmctld.log
SlurmdLogFile=$STATE/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
SlurmdParameters=config_overrides
SchedulerParameters=sched_interval=2
MinJobAge=600
NodeName=$HOST NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$mem_mb State=UNKNOWN
PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF
}

node_ready() {
    local s
    s="$(sinfo -h -N -o %T 2>/dev/null | head -n1)" || return 1
    case "$s" in idle*|mixed*|alloc*|completing*) return 0 ;; *) return 1 ;; esac
}

start() {
    install_packages
    as_root mkdir -p "$STATE/ctld" "$STATE/d"
    start_munge
    write_conf
    if ! alive "$STATE/slurmctld.pid"; then
        as_root /usr/sbin/slurmctld || die "slurmctld did not start (see $STATE/slurmctld.log)"
        touch "$STATE/started-slurmctld"
    fi
    if ! alive "$STATE/slurmd.pid"; then
        as_root /usr/sbin/slurmd || die "slurmd did not start (see $STATE/slurmd.log)"
        touch "$STATE/started-slurmd"
    fi
    for i in $(seq 120); do
        if node_ready; then
            note "node $HOST up ($(nproc) CPUs); state in $STATE"
            return
        fi
        # A node left down or drained by an earlier run is put back.
        if [ $((i % 10)) -eq 0 ]; then
            scontrol update nodename="$HOST" state=resume >/dev/null 2>&1 || true
        fi
        sleep 0.5
    done
    sinfo -N >&2 || true
    tail -n 20 "$STATE/slurmctld.log" "$STATE/slurmd.log" >&2 || true
    die "the node did not become idle within 60 s"
}

stop_one() {
    local name="$1" pidfile="$2"
    if alive "$pidfile"; then
        local pid
        pid="$(cat "$pidfile")"
        as_root kill "$pid" 2>/dev/null || true
        for _ in $(seq 100); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
        kill -0 "$pid" 2>/dev/null && as_root kill -9 "$pid" 2>/dev/null || true
        note "stopped $name ($pid)"
    fi
}

stop() {
    [ -f "$STATE/started-slurmd" ] && stop_one slurmd "$STATE/slurmd.pid"
    [ -f "$STATE/started-slurmctld" ] && stop_one slurmctld "$STATE/slurmctld.pid"
    [ -f "$STATE/munged.pid" ] && stop_one munged "$STATE/munged.pid"
    rm -f "$STATE/started-slurmd" "$STATE/started-slurmctld" "$STATE/munged.pid"
    if [ -f "$CONF" ] && grep -qF "$MARK" "$CONF"; then
        as_root rm -f "$CONF"
    fi
}

case "${1:-}" in
    start) mkdir -p "$STATE"; start ;;
    stop) stop ;;
    status) node_ready ;;
    *) echo "usage: $0 start|stop|status" >&2; exit 2 ;;
esac
