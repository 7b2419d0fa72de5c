#!/usr/bin/env bash
# cluster.sh start|stop DIR - a private one-node Slurm cluster on this
# machine (munged, slurmctld, slurmd), for the test of the precompute array
# job. Depends on Debian's slurm-wlm and munge and on slurm.conf.in beside
# this script. Must run as root (slurmd starts jobs as their user).
#
#   start DIR   DIR must be an empty folder whose parents all users may
#               search (munged requires it of its socket). Writes a MUNGE key, the
#               config (DIR/slurm.conf) and every state, spool, log and pid
#               file into DIR, starts the three daemons and waits until the
#               node is idle. Writes DIR/env, which sets SLURM_CONF for the
#               client commands (sbatch, squeue, sinfo), and DIR/mark,
#               NAME=VALUE of the variable that marks the daemons: give it
#               to the jobs too (env "$(cat DIR/mark)" sbatch ...) and stop
#               ends any of them left behind.
#   stop DIR    cancels the cluster's jobs, stops its daemons by their pid
#               files, then ends any process still marked as started under
#               DIR (a job step left behind). Safe to run twice, or after a
#               failed start.
set -u
here="$(cd "$(dirname "$0")" && pwd)"

# how long the node may take to come up idle: slurmd registers within a
# second or two here; 60 s leaves room for a loaded machine
START_TIMEOUT_S=60
# how long a daemon gets to exit after SIGTERM before SIGKILL: slurmctld
# saves its state on the way out, which takes well under a second here
STOP_WAIT_S=10
# the daemons carry this variable (with DIR as its value), so that stop can
# find what they left behind without touching anything else's processes
MARK=HL_SLURM_TEST_CLUSTER

die() { echo "cluster: $*" >&2; exit 1; }

# free_port: a TCP port nothing on 127.0.0.1 listens on, from 20000..29999
# (below Linux's ephemeral range, so no client socket takes it meanwhile)
free_port() {
  local p tries=0
  while [ "$tries" -lt 200 ]; do
    p=$((20000 + RANDOM % 10000))
    if ! (exec 3<>"/dev/tcp/127.0.0.1/$p") 2>/dev/null; then
      [ "$p" != "${1:-}" ] && { echo "$p"; return 0; }
    fi
    tries=$((tries + 1))
  done
  return 1
}

# wait_gone PID SECONDS: 0 once PID has exited
wait_gone() {
  local i=0
  while kill -0 "$1" 2>/dev/null; do
    [ "$i" -ge $(( $2 * 10 )) ] && return 1
    sleep 0.1
    i=$((i + 1))
  done
  return 0
}

# stop_pidfile FILE NAME: SIGTERM the daemon in FILE, SIGKILL if it stays
stop_pidfile() {
  local f="$1" pid
  [ -s "$f" ] || return 0
  pid="$(tr -dc 0-9 <"$f")"
  [ -n "$pid" ] || return 0
  # the pid file may be stale: only a process carrying our mark is ours
  tr '\0' '\n' 2>/dev/null <"/proc/$pid/environ" | grep -qx "$MARK=$dir" || return 0
  kill -TERM "$pid" 2>/dev/null
  if ! wait_gone "$pid" "$STOP_WAIT_S"; then
    echo "cluster: $2 (pid $pid) ignored SIGTERM for ${STOP_WAIT_S} s; SIGKILL" >&2
    kill -KILL "$pid" 2>/dev/null
    wait_gone "$pid" 5
  fi
  echo "cluster: stopped $2 (pid $pid)"
}

# marked_pids: processes whose environment carries our mark for this DIR
marked_pids() {
  local e pid
  for e in /proc/[0-9]*/environ; do
    pid="${e#/proc/}"; pid="${pid%/environ}"
    [ "$pid" = "$$" ] && continue
    tr '\0' '\n' 2>/dev/null <"$e" | grep -qx "$MARK=$dir" && echo "$pid"
  done
  return 0
}

start() {
  [ "$(id -u)" -eq 0 ] || die "must run as root (slurmd runs jobs as their user)"
  [ -d "$dir" ] || die "$dir is not a folder"
  [ -z "$(ls -A "$dir")" ] || die "$dir is not empty"
  mkdir -p "$dir"/{munge,socket,state,spool,run,log} || die "cannot make folders in $dir"
  # munged wants its socket's folders searchable by all (every user
  # must reach it) and its key folder private
  chmod 711 "$dir" && chmod 755 "$dir/socket" && chmod 700 "$dir/munge" \
    || die "cannot set the permissions in $dir"
  local host ctld_port slurmd_port
  host="$(hostname -s)"
  ctld_port="$(free_port)" || die "no free TCP port in 20000..29999"
  slurmd_port="$(free_port "$ctld_port")" || die "no free TCP port in 20000..29999"
  sed -e "s|@HOST@|$host|g" -e "s|@DIR@|$dir|g" \
      -e "s|@CTLD_PORT@|$ctld_port|g" -e "s|@SLURMD_PORT@|$slurmd_port|g" \
      "$here/slurm.conf.in" >"$dir/slurm.conf" || die "cannot write $dir/slurm.conf"
  echo "export SLURM_CONF='$dir/slurm.conf'" >"$dir/env"
  echo "$MARK=$dir" >"$dir/mark"
  export SLURM_CONF="$dir/slurm.conf"
  export "$MARK=$dir"

  # a private MUNGE key (1024 random bytes, the most munged takes) and daemon
  # on its own socket (slurm.conf's AuthInfo): the system's munged, if
  # any, is neither needed nor touched
  head -c 1024 /dev/urandom >"$dir/munge/munge.key" && chmod 400 "$dir/munge/munge.key" \
    || die "cannot write the MUNGE key"
  munged --socket="$dir/socket/munge.socket" --key-file="$dir/munge/munge.key" \
         --pid-file="$dir/run/munged.pid" --log-file="$dir/log/munged.log" \
         --seed-file="$dir/munge/munged.seed" \
    || die "munged did not start ($(tail -n 3 "$dir/log/munged.log" 2>/dev/null | tr '\n' ' '))"
  slurmctld -c -f "$dir/slurm.conf" \
    || die "slurmctld did not start ($(tail -n 3 "$dir/log/slurmctld.log" 2>/dev/null | tr '\n' ' '))"
  slurmd -f "$dir/slurm.conf" -N "$host" \
    || die "slurmd did not start ($(tail -n 3 "$dir/log/slurmd.log" 2>/dev/null | tr '\n' ' '))"

  local i=0 state=""
  while [ "$i" -lt $(( START_TIMEOUT_S * 2 )) ]; do
    state="$(sinfo -h -n "$host" -o %t 2>/dev/null)"
    [ "$state" = idle ] && break
    sleep 0.5
    i=$((i + 1))
  done
  [ "$state" = idle ] || die "node $host not idle after ${START_TIMEOUT_S} s (state '${state:-none}'); see $dir/log"
  echo "cluster: node $host idle after $(( i / 2 )) s (slurmctld port $ctld_port, slurmd port $slurmd_port, config $dir/slurm.conf)"
}

stop() {
  [ -d "$dir" ] || return 0
  [ -f "$dir/slurm.conf" ] || [ -d "$dir/run" ] || { echo "cluster: no cluster in $dir; nothing stopped"; return 0; }
  if [ -s "$dir/run/slurmctld.pid" ] && [ -f "$dir/slurm.conf" ]; then
    SLURM_CONF="$dir/slurm.conf" scancel --quiet --partition=hltest 2>/dev/null
  fi
  stop_pidfile "$dir/run/slurmd.pid" slurmd
  stop_pidfile "$dir/run/slurmctld.pid" slurmctld
  stop_pidfile "$dir/run/munged.pid" munged
  # job steps (slurmstepd and what it ran) outlive slurmd; end ours
  local pid left
  left="$(marked_pids)"
  for pid in $left; do
    echo "cluster: ending leftover process $pid ($(tr '\0' ' ' <"/proc/$pid/cmdline" 2>/dev/null | head -c 80))"
    kill -KILL "$pid" 2>/dev/null
  done
  for pid in $left; do wait_gone "$pid" 5; done
  left="$(marked_pids)"
  [ -z "$left" ] || die "processes still running after stop: $left"
  return 0
}

[ $# -eq 2 ] || { echo "usage: $0 start|stop DIR" >&2; exit 2; }
dir="$(cd "$2" 2>/dev/null && pwd)" || die "$2 is not a folder"
case "$1" in
  start) start ;;
  stop) stop ;;
  *) echo "usage: $0 start|stop DIR" >&2; exit 2 ;;
esac
