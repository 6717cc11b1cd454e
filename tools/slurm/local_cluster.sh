#!/usr/bin/env bash
# Throwaway one-node Slurm cluster for CI and integration tests (Debian 12, as root,
# no systemd): daemons are started directly; config, munge key, state, logs and pid
# files all live under DIR, nothing in /etc is used.
#   local_cluster.sh install     apt-get the packages (no-op if already installed)
#   local_cluster.sh start DIR   write config, start munged+slurmctld+slurmd, wait for idle
#   local_cluster.sh stop DIR    cancel jobs, stop the daemons (no-op if not running)
# Then `source DIR/env.sh` (sets SLURM_CONF) before sbatch/squeue/sinfo.
# Clients reach the daemons on 127.0.0.1, but the daemons listen on all addresses:
# CommunicationParameters=NoCtldInAddrAny would bind to what `hostname` resolves to,
# which breaks when it does not resolve (or resolves to a non-loopback address).
set -euo pipefail

PKGS=(munge slurmctld slurmd slurm-client)
CTLD_PORT=${SLURM_TEST_CTLD_PORT:-16817}   # not the default 6817, so a real cluster can coexist
SLURMD_PORT=${SLURM_TEST_SLURMD_PORT:-16818}
WAIT_SECS=${SLURM_TEST_WAIT_SECS:-60}

die() { echo "local_cluster: $*" >&2; exit 1; }

do_install() {
  local missing=() p
  for p in "${PKGS[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'ok installed' || missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  export DEBIAN_FRONTEND=noninteractive
  # The postinst scripts try to start the system-wide daemons (with /etc config);
  # we start our own, so deny service starts while installing unless a policy exists.
  if [ ! -e /usr/sbin/policy-rc.d ]; then
    printf '#!/bin/sh\nexit 101\n' >/usr/sbin/policy-rc.d && chmod +x /usr/sbin/policy-rc.d
    trap 'rm -f /usr/sbin/policy-rc.d' EXIT
  fi
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
}

# Is the daemon named $2 running with the pid recorded in file $1?
alive() {
  local pid
  pid=$(cat "$1" 2>/dev/null) || return 1
  [ -n "$pid" ] && [[ "$(cat "/proc/$pid/comm" 2>/dev/null)" == "$2"* ]]
}

# Fail early with a clear message if something already listens on port $1
# (bash /dev/tcp: no dependency on iproute2, which minimal images lack).
port_free() {
  if (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null; then
    die "port $1 already in use (set SLURM_TEST_CTLD_PORT / SLURM_TEST_SLURMD_PORT)"
  fi
}

write_conf() {
  local d=$1 host=$2 mem
  # Half of RAM capped at 1 GiB: slurmd drains the node if RealMemory exceeds what it sees.
  mem=$(awk '/MemTotal/ { m = int($2 / 2048); print (m > 1024 ? 1024 : m) }' /proc/meminfo)
  cat >"$d/slurm.conf" <<EOF
ClusterName=localtest
# Controller address is loopback, so no DNS or real network is needed.
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$CTLD_PORT
SlurmdPort=$SLURMD_PORT
# Everything runs as root: there is no slurm user to drop to in a throwaway container.
SlurmUser=root
SlurmdUser=root
# Our private munged, not the system one at /run/munge.
AuthType=auth/munge
AuthInfo=socket=$d/run/munge.socket
CredType=cred/munge
# State, spool, logs and pid files all under DIR.
StateSaveLocation=$d/state
SlurmdSpoolDir=$d/spool
SlurmctldPidFile=$d/run/slurmctld.pid
SlurmdPidFile=$d/run/slurmd.pid
SlurmctldLogFile=$d/log/slurmctld.log
SlurmdLogFile=$d/log/slurmd.log
# No cgroups and no systemd: plain /proc process tracking, no task binding.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
# No slurmdbd: sacct will not work, use squeue / sbatch --wait.
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
# No mail binary in a container; avoids an error at every start.
MailProg=/bin/true
# Count plain CPUs so several 1-CPU jobs (array tasks) share the node.
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
# A node that was down comes back by itself once slurmd registers.
ReturnToService=2
NodeName=$host NodeHostname=$host NodeAddr=127.0.0.1 CPUs=$(nproc) RealMemory=$mem State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
  echo "export SLURM_CONF=$d/slurm.conf" >"$d/env.sh"
}

do_start() {
  mkdir -p "$1"
  local d host
  d=$(cd "$1" && pwd)   # absolute: the paths go into slurm.conf
  host=$(hostname -s)
  # munged wants its key dir private and its socket dir world-searchable,
  # neither group/world-writable (so DIR must not be e.g. a 0777 dir).
  mkdir -p "$d"/{munge,state,spool,log,run}
  chmod 700 "$d/munge"
  chmod 755 "$d" "$d/run"
  write_conf "$d" "$host"
  export SLURM_CONF=$d/slurm.conf

  alive "$d/run/slurmctld.pid" slurmctld || port_free "$CTLD_PORT"   # check before starting anything
  alive "$d/run/slurmd.pid" slurmd || port_free "$SLURMD_PORT"
  if ! alive "$d/run/munged.pid" munged; then
    [ -s "$d/munge/munge.key" ] || mungekey --create --keyfile="$d/munge/munge.key"
    chmod 600 "$d/munge/munge.key"
    munged --socket="$d/run/munge.socket" --key-file="$d/munge/munge.key" \
      --pid-file="$d/run/munged.pid" --log-file="$d/log/munged.log" \
      --seed-file="$d/munge/munged.seed" --origin=127.0.0.1  # origin: hostname may not resolve
  fi
  alive "$d/run/slurmctld.pid" slurmctld || slurmctld -f "$SLURM_CONF"
  alive "$d/run/slurmd.pid" slurmd || slurmd -f "$SLURM_CONF"

  local i f state=
  for ((i = 0; i < WAIT_SECS; i++)); do
    state=$(sinfo -h -N -n "$host" -o %t 2>/dev/null || true)
    [ "$state" = idle ] && break
    sleep 1
  done
  if [ "$state" != idle ]; then
    echo "local_cluster: node $host not idle after ${WAIT_SECS}s (state: '${state}')" >&2
    for f in "$d"/log/*; do echo "===== $f" >&2; tail -n 40 "$f" >&2 || true; done
    do_stop "$d"
    exit 1
  fi
  echo "local_cluster: node $host idle after ${i}s"
  cat "$d/env.sh"
}

do_stop() {
  local d=$1 name i
  [ -d "$d" ] || return 0
  d=$(cd "$d" && pwd)
  # Cancel leftover jobs first, so no slurmstepd outlives slurmd.
  if alive "$d/run/slurmctld.pid" slurmctld; then
    SLURM_CONF=$d/slurm.conf scancel --quiet --user="$(id -un)" 2>/dev/null || true
    for ((i = 0; i < 10; i++)); do
      [ -z "$(SLURM_CONF=$d/slurm.conf squeue -h -o %A 2>/dev/null)" ] && break
      sleep 1
    done
  fi
  # TERM all at once (each takes 1-2 s to exit), wait up to 10 s, then KILL.
  local pids=() pid
  for name in slurmd slurmctld munged; do
    alive "$d/run/$name.pid" "$name" && pids+=("$(cat "$d/run/$name.pid")")
  done
  [ ${#pids[@]} -gt 0 ] && kill "${pids[@]}" 2>/dev/null || true
  for pid in "${pids[@]}"; do
    for ((i = 0; i < 50; i++)); do kill -0 "$pid" 2>/dev/null || break; sleep 0.2; done
    kill -9 "$pid" 2>/dev/null || true
  done
  rm -f "$d"/run/*.pid
}

case "${1:-}" in
  install) do_install ;;
  start) [ $# -eq 2 ] || die "usage: $0 start DIR"; do_start "$2" ;;
  stop) [ $# -eq 2 ] || die "usage: $0 stop DIR"; do_stop "$2" ;;
  *) die "usage: $0 install | start DIR | stop DIR" ;;
esac
