#!/usr/bin/env bash
# Regenerates tests/deploy/netns/results.md: the frame rate of rtc-master + 3 rtc-workers on
# separate hosts (network namespaces, 100 Mbit/s links) for every wire format and compression at
# 512x512 and 1024x1024, next to the master's link bound and iperf3's goodput. Not a CI test
# (about 3-5 minutes); needs root, iproute2 and optionally iperf3.
#
#   sudo tests/deploy/netns/fps_table.sh [FRAMES]        (default 10 frames per configuration)
#
# RTC_BUILD_DIR picks the build (default build/release; rtc-master, rtc-worker, rtc-render built).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../../.." && pwd)"
build="${RTC_BUILD_DIR:-$root/build/release}"
frames="${1:-10}"
if ! [[ "$frames" =~ ^[0-9]+$ ]] || [ "$frames" -lt 2 ]; then echo "fps_table: FRAMES must be a number >= 2" >&2; exit 2; fi
for b in master/rtc-master worker/rtc-worker worker/rtc-render; do
  [ -x "$build/$b" ] || { echo "fps_table: $build/$b not built (cmake --build --preset release --target rtc-master rtc-worker rtc-render)" >&2; exit 1; }
done
[ "$(id -u)" = 0 ] || { echo "fps_table: needs root (network namespaces)" >&2; exit 1; }

table="$(mktemp "${TMPDIR:-/tmp}/rtc-fps-table.XXXXXX")"
trap 'rm -f "$table"' EXIT
load_before="$(cut -d' ' -f1 /proc/loadavg)"
started="$(date -u '+%Y-%m-%d %H:%M UTC')"
status=0
NETNS_TIME_LIMIT_S=1200 "$here/with_netns_cluster.sh" 3 100mbit python3 "$here/netns_cluster_test.py" table \
  --master "$build/master/rtc-master" --worker "$build/worker/rtc-worker" --render "$build/worker/rtc-render" \
  --frames "$frames" --out "$table" || status=$?
if [ "$status" -ne 0 ] || [ ! -s "$table" ]; then
  echo "fps_table: the run failed (status $status); results.md left as it was" >&2
  exit 1
fi
{
  echo "# Frame rate on separate hosts under a 100 Mbit/s link"
  echo
  echo "Regenerate with \`sudo tests/deploy/netns/fps_table.sh $frames\` (after building rtc-master, rtc-worker"
  echo "and rtc-render in build/release). Measured $started on $(nproc) cores, load average $load_before"
  echo "before the run, commit $(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo unknown)."
  echo
  echo "A row is link-bound when it reaches 90% of the master's bound. The CPU-bound rows depend on"
  echo "what else the 2 shared cores run: read them with the cluster's CPU use and the machine's."
  echo
  cat "$table"
} > "$here/results.md"
cat "$here/results.md"
