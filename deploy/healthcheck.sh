#!/bin/sh
# Container health for deploy/Dockerfile's HEALTHCHECK and the Kubernetes probes, judged from the
# container's own network namespace (/proc/net/tcp*): rtc-master is healthy once it listens for
# workers (it writes --ready-file at the same moment), rtc-worker while it holds a connection to
# its master (it reconnects with back-off when the master goes). Exit 0 healthy, 1 not.
# Usage: rtc-healthcheck [master|worker]   (default: what runs as PID 1)
set -eu

role="${1:-}"
if [ -z "$role" ]; then
  case "$(cat /proc/1/comm 2>/dev/null)" in
    rtc-master) role=master ;;
    rtc-worker) role=worker ;;
    *) echo "rtc-healthcheck: PID 1 is $(cat /proc/1/comm 2>/dev/null || echo unknown), not rtc-master or rtc-worker; nothing to check"; exit 0 ;;
  esac
fi

# /proc/net/tcp{,6} column 4 is the socket state: 0A listening, 01 established.
count_state() {
  cat /proc/net/tcp /proc/net/tcp6 2>/dev/null | awk -v s="$1" 'NR > 1 && $4 == s { n++ } END { print n + 0 }'
}

case "$role" in
  master)
    n="$(count_state 0A)"
    [ "$n" -gt 0 ] || { echo "rtc-master is not listening (yet)"; exit 1; }
    echo "rtc-master listening; $(count_state 01) connections" ;;
  worker)
    n="$(count_state 01)"
    [ "$n" -gt 0 ] || { echo "rtc-worker holds no connection to a master (connecting or retrying)"; exit 1; }
    echo "rtc-worker connected" ;;
  *) echo "rtc-healthcheck: unknown role \"$role\" (master or worker)"; exit 1 ;;
esac
