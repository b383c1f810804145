#!/usr/bin/env bash
# Runs a command next to a fake LAN of separate hosts (netns-cluster.sh: a master and K worker
# namespaces, each link capped at RATE) and removes the LAN on every exit path.
#
#   with_netns_cluster.sh K RATE COMMAND [ARG...]
#
# The command runs in the root namespace with NETNS_SCRIPT (netns-cluster.sh), PREFIX and SUBNET
# exported: `"$NETNS_SCRIPT" exec master|wI PROGRAM ...` starts a program on a host; the master
# is ${SUBNET}.1. PREFIX ("rtn<pid>") and SUBNET (from the pid) are this run's own, so parallel
# runs do not collide, and namespaces left by a run that was killed with SIGKILL (ctest's
# timeout) are removed by the next run once that run's pid is gone.
# NETNS_TIME_LIMIT_S (optional): stop the command (SIGTERM, SIGKILL 10 s later) after that many
# seconds, so the cleanup runs before an outer timeout could kill this script outright.
# Exit status: the command's (124 when it ran out of time); 77 (skip) when namespaces cannot be made here (not root, no
# iproute2, no permission); 1 when something of the LAN is left behind or it cannot be built.
set -euo pipefail

here="$(cd "$(dirname "$0")" && pwd)"
NETNS_SCRIPT="$here/netns-cluster.sh"
skip() { echo "SKIP: $*" >&2; exit 77; }
die() { echo "with_netns_cluster: $*" >&2; exit 1; }

[ $# -ge 3 ] || die "usage: with_netns_cluster.sh K RATE COMMAND [ARG...]"
k="$1" rate="$2"
shift 2

[ "$(id -u)" = 0 ] || skip "separate-hosts test needs root to create network namespaces (running as uid $(id -u))"
command -v ip >/dev/null 2>&1 || skip "separate-hosts test needs iproute2 (ip): apt-get install iproute2 (deploy/install-deps.sh)"
command -v tc >/dev/null 2>&1 || skip "separate-hosts test needs iproute2 (tc): apt-get install iproute2 (deploy/install-deps.sh)"

PREFIX="rtn$$"
SUBNET="10.$((64 + ($$ >> 8) % 128)).$(($$ & 255))"
export PREFIX SUBNET NETNS_SCRIPT

# Leftovers of earlier runs killed before their trap could run: rtn<pid>-* whose pid is gone.
for ns in $(ip netns list | awk '{print $1}' | grep -E '^rtn[0-9]+-(sw|master|w[0-9]+)$' || true); do
  pid="${ns%%-*}"
  pid="${pid#rtn}"
  if [ "$pid" != "$$" ] && ! kill -0 "$pid" 2>/dev/null; then
    echo "with_netns_cluster: removing $ns, left by run $pid (no longer running)" >&2
    ip netns del "$ns" 2>/dev/null || true
    rm -f "/run/rtn$pid-netns-cluster.k"
  fi
done

# Can this machine make a namespace at all (a container without CAP_SYS_ADMIN cannot)?
probe_err="$(ip netns add "${PREFIX}-probe" 2>&1)" ||
  skip "cannot create a network namespace here: $probe_err"
ip netns del "${PREFIX}-probe"

child=""
cleaned=0
cleanup() {
  local rc=$?
  [ "$cleaned" = 1 ] && return
  cleaned=1
  trap - EXIT INT TERM
  if [ -n "$child" ] && kill -0 "$child" 2>/dev/null; then
    kill -TERM "$child" 2>/dev/null || true
    for _ in $(seq 1 100); do kill -0 "$child" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "$child" 2>/dev/null || true
    wait "$child" 2>/dev/null || true
  fi
  "$NETNS_SCRIPT" down >/dev/null 2>&1 || true
  if ! left="$("$NETNS_SCRIPT" leftovers 2>&1)"; then
    echo "with_netns_cluster: left behind after down:" >&2
    echo "$left" >&2
    rc=1
  else
    echo "with_netns_cluster: namespaces of $PREFIX removed, nothing left"
  fi
  exit "$rc"
}
trap cleanup EXIT
trap 'echo "with_netns_cluster: interrupted" >&2; exit 130' INT
trap 'echo "with_netns_cluster: terminated" >&2; exit 143' TERM

"$NETNS_SCRIPT" up "$k" "$rate" || die "could not build the LAN ($k workers, $rate)"
limit="${NETNS_TIME_LIMIT_S:-0}"
[[ "$limit" =~ ^[0-9]+$ ]] || die "NETNS_TIME_LIMIT_S must be whole seconds (got '$limit')"
runner=()
[ "$limit" -gt 0 ] && runner=(timeout -k 10 "$limit")
# The command runs in the background so that a signal reaches the trap at once.
"${runner[@]}" "$@" &
child=$!
status=0
wait "$child" || status=$?
child=""
exit "$status"
