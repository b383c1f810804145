#!/usr/bin/env bash
# netns-cluster.sh — a fake LAN on one machine for testing the render cluster:
# one "master" host and K "worker" hosts, each its own network namespace, joined
# by a Linux bridge that lives in its own "switch" namespace, every host link capped
# with tc tbf (default 100 Mbit/s, like the paper's 100 Mbit Ethernet).
# Nothing here touches the root namespace's interfaces, routes or firewall, and the
# namespaces have no default route: traffic can only go between these hosts.
#
# Copied from the workplace notes (../shared/notes/netns-cluster.sh, described in
# ../shared/notes/infra.md section 2) for rtc's separate-hosts tests (tests/deploy/netns);
# changed here: OVERHEAD (tbf counts real Ethernet's per-frame bytes), PREFIX/SUBNET checked,
# `down` also removes veth ends a failed `up` left in the root namespace, `leftovers`.
#
# Needs root and iproute2 (ip, tc). iperf3 (apt) is optional, for `selftest`.
# Nothing runs unless a command is given.
#
#   sudo ./netns-cluster.sh up K [RATE]      # e.g. up 4 100mbit ; RATE=none -> no cap
#   sudo ./netns-cluster.sh status
#   sudo ./netns-cluster.sh exec master ./render_master --port 7000 ...
#   sudo ./netns-cluster.sh exec w1 ./render_worker --connect 10.77.0.1:7000
#   sudo ./netns-cluster.sh selftest         # bounded 20 MB transfer w1 -> master
#   sudo ./netns-cluster.sh down
#   sudo ./netns-cluster.sh leftovers        # lists this PREFIX's namespaces/links; exit 1 if any
#
# Addresses: master 10.77.0.1, worker i (1..K) 10.77.0.(10+i), /24, no gateway.
# Environment: PREFIX (namespace prefix, default rc), SUBNET (default 10.77.0),
#   BURST (tbf burst, default 32kbit), LATENCY (tbf queue latency, default 400ms),
#   OVERHEAD (bytes tbf adds to each packet, default 24: tbf counts from the MAC header, a real
#     Ethernet wire also carries preamble 8 + FCS 4 + inter-frame gap 12; with it a 100mbit link
#     gives TCP 94.1 Mbit/s like Fast Ethernet, without it 95.6),
#   DELAY (e.g. 1ms; uses netem, which this workplace's kernel LACKS -> warning only).
set -euo pipefail

PREFIX=${PREFIX:-rc}
SUBNET=${SUBNET:-10.77.0}
BURST=${BURST:-32kbit}
LATENCY=${LATENCY:-400ms}
OVERHEAD=${OVERHEAD:-24}
DELAY=${DELAY:-}
SW="${PREFIX}-sw"
STATE="/run/${PREFIX}-netns-cluster.k"
MAXK=60

die() { echo "netns-cluster: $*" >&2; exit 1; }
[ "$(id -u)" = 0 ] || die "must run as root"
command -v ip >/dev/null || die "ip not found (apt-get install -y iproute2)"
command -v tc >/dev/null || die "tc not found (apt-get install -y iproute2)"
# Interface names "<PREFIX>t<n>" must fit the kernel's 15 characters.
[[ "$PREFIX" =~ ^[a-z][a-z0-9]{0,9}$ ]] || die "PREFIX must be 1-10 lower-case letters/digits, starting with a letter (got '$PREFIX')"
[[ "$SUBNET" =~ ^[0-9]{1,3}\.[0-9]{1,3}\.[0-9]{1,3}$ ]] || die "SUBNET must be three octets like 10.77.0 (got '$SUBNET')"
[[ "$OVERHEAD" =~ ^[0-9]+$ ]] || die "OVERHEAD must be a byte count (got '$OVERHEAD')"

host_ns()  { if [ "$1" = master ]; then echo "${PREFIX}-master"; else echo "${PREFIX}-$1"; fi; }
host_ip()  { if [ "$1" = master ]; then echo "${SUBNET}.1"; else echo "${SUBNET}.$((10 + ${1#w}))"; fi; }
hosts()    { local k; k=$(cat "$STATE" 2>/dev/null || echo 0); echo master; for i in $(seq 1 "$k"); do echo "w$i"; done; }

# shape NS DEV: egress cap (and optional delay) on DEV inside namespace NS
shape() {
  local ns=$1 dev=$2 rate=$3
  if [ -n "$DELAY" ]; then
    if ip netns exec "$ns" tc qdisc add dev "$dev" root handle 1: netem delay "$DELAY" limit 10000 2>/dev/null; then
      [ "$rate" = none ] || ip netns exec "$ns" tc qdisc add dev "$dev" parent 1: handle 2: tbf rate "$rate" burst "$BURST" latency "$LATENCY" overhead "$OVERHEAD"
      return
    fi
    echo "netns-cluster: warning: netem not available in this kernel, DELAY=$DELAY ignored" >&2
  fi
  [ "$rate" = none ] || ip netns exec "$ns" tc qdisc add dev "$dev" root tbf rate "$rate" burst "$BURST" latency "$LATENCY" overhead "$OVERHEAD"
}

up() {
  local k=${1:-2} rate=${2:-100mbit}
  if ! [[ "$k" =~ ^[0-9]+$ ]] || [ "$k" -lt 1 ] || [ "$k" -gt "$MAXK" ]; then die "K must be 1..$MAXK"; fi
  [ -e "$STATE" ] && die "already up (run: $0 down)"
  echo "$k" > "$STATE"
  ip netns add "$SW"
  ip -n "$SW" link set lo up
  ip -n "$SW" link add br0 type bridge
  ip -n "$SW" link set br0 up
  local h ns n=0
  for h in $(hosts); do
    ns=$(host_ns "$h"); n=$((n + 1))
    ip netns add "$ns"
    ip -n "$ns" link set lo up
    # veth: "eth0" inside the host namespace, "p-<host>" on the switch
    ip link add "${PREFIX}t$n" type veth peer name "${PREFIX}s$n"
    ip link set "${PREFIX}t$n" netns "$ns"
    ip link set "${PREFIX}s$n" netns "$SW"
    ip -n "$ns" link set "${PREFIX}t$n" name eth0
    ip -n "$SW" link set "${PREFIX}s$n" name "p-$h"
    ip -n "$SW" link set "p-$h" master br0
    ip -n "$ns" addr add "$(host_ip "$h")/24" dev eth0
    ip -n "$ns" link set eth0 up
    ip -n "$SW" link set "p-$h" up
    shape "$ns" eth0 "$rate"        # host -> switch (upload)
    shape "$SW" "p-$h" "$rate"      # switch -> host (download)
    echo "$h: netns $ns, ip $(host_ip "$h"), link $rate"
  done
}

down() {
  local h n=0
  for h in $(hosts); do
    n=$((n + 1))
    ip netns del "$(host_ns "$h")" 2>/dev/null || true
    # An `up` that failed between creating a veth pair and moving it leaves it here.
    ip link del "${PREFIX}t$n" 2>/dev/null || true
  done
  ip netns del "$SW" 2>/dev/null || true
  rm -f "$STATE"
  echo "netns-cluster: down"
}

# leftovers: this PREFIX's namespaces, root-namespace links and state file; exit 1 if any.
leftovers() {
  local found
  found=$( { ip netns list | awk '{print "netns " $1}' | grep -E "^netns ${PREFIX}-(sw|master|w[0-9]+)\$" || true
             ip -o link show | awk -F': ' '{print "link " $2}' | grep -E "^link ${PREFIX}[ts][0-9]+(@|\$)" || true
             if [ -e "$STATE" ]; then echo "file $STATE"; fi; } )
  if [ -n "$found" ]; then
    echo "$found"
    return 1
  fi
  echo "netns-cluster: nothing left for PREFIX=$PREFIX"
}

status() {
  [ -e "$STATE" ] || { echo "netns-cluster: not up"; return 0; }
  local h
  for h in $(hosts); do
    echo "== $h ($(host_ns "$h"))"
    ip -n "$(host_ns "$h")" -br addr show eth0
    ip netns exec "$(host_ns "$h")" tc qdisc show dev eth0
  done
}

selftest() {
  [ -e "$STATE" ] || die "not up"
  command -v iperf3 >/dev/null || die "iperf3 not found (apt-get install -y iperf3)"
  ip netns exec "$(host_ns master)" timeout 60 iperf3 -s -1 -p 5201 >/dev/null 2>&1 &
  local s=$!; sleep 0.5
  ip netns exec "$(host_ns w1)" timeout 60 iperf3 -c "$(host_ip master)" -p 5201 -n 20M -f m | grep -E 'receiver|sender'
  wait "$s" || true
}

cmd=${1:-}; shift || true
case "$cmd" in
  up) up "$@" ;;
  down) down ;;
  status) status ;;
  leftovers) leftovers ;;
  selftest) selftest ;;
  exec) h=${1:?host}; shift; exec ip netns exec "$(host_ns "$h")" "$@" ;;
  *) sed -n '2,33p' "$0"; exit 2 ;;
esac
