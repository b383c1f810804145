#!/usr/bin/env bash
# One kd-tree build option at two values against each other: rtc-bench on every view of
# the shared scene pack, one thread, the widest packets the CPU has (ab_loop.sh's AB_ISA),
# process CPU time, the values alternating view by view, ROUNDS times. Writes tests/bench/results/NAME.txt (one line per view,
# value, round and mode: scene value round mode Mrays/s build_ms nodes SAH triangles) and NAME.md
# (the loop is tests/bench/ab_loop.sh; summarize_kd_ab.py: per view the median ratio of the second
# value's throughput to the first's, paired round by round, and the build times).
# Usage: tests/bench/run_kd_ab.sh OPTION "VALUES" NAME [SCENES_DIR] [ROUNDS]
#   e.g. tests/bench/run_kd_ab.sh --kd-mask-below "0 64" kd_mask
# RTC_BENCH: the rtc-bench binary (default build/release/tests/bench/rtc-bench)
set -euo pipefail
cd "$(dirname "$0")/../.."
[ $# -ge 3 ] || { echo "usage: $0 OPTION \"VALUES\" NAME [SCENES_DIR] [ROUNDS]" >&2; exit 2; }
option=$1
values=$2
name=$3
scenes=${4:-../shared/scenes}
rounds=${5:-3}
bench=${RTC_BENCH:-build/release/tests/bench/rtc-bench}
[ "$(echo $values | wc -w)" -eq 2 ] || { echo "run_kd_ab: VALUES must be two values, got \"$values\"" >&2; exit 2; }
[ -d "$scenes" ] || { echo "run_kd_ab: $scenes is not a folder (the shared scene pack)" >&2; exit 1; }
if [ -n "${RTC_BENCH:-}" ]; then
  [ -x "$bench" ] || { echo "run_kd_ab: RTC_BENCH=$bench is not an executable" >&2; exit 1; }
elif [ ! -x "$bench" ]; then
  cmake --preset release >/dev/null && cmake --build --preset release --target rtc-bench
fi
set -- $values
exec tests/bench/ab_loop.sh "$name" "$scenes" "$rounds" "$option" "$1" "$bench" "$option $1" "$2" "$bench" "$option $2"
