#!/usr/bin/env bash
# Repeated kd-tree builds of two rtc-bench binaries against each other (a build change, before
# and after): for each view, ROUNDS rounds of one process per binary, alternating, each timing
# BUILDS builds at THREADS threads (wall time) and reporting its median (`build_ms`). Prints per
# view both binaries' medians round by round and the ratio B over A, paired by round: its
# median and the rounds' range.
# Usage: tests/bench/run_build_ab.sh BIN_A BIN_B ROUNDS THREADS BUILDS VIEW...
#   VIEW: a view file, e.g. ../shared/scenes/bunny/view.json
#   e.g. cp build/release/tests/bench/rtc-bench /tmp/before; (change, rebuild);
#        tests/bench/run_build_ab.sh /tmp/before build/release/tests/bench/rtc-bench 9 2 31 \
#          ../shared/scenes/bunny/view.json ../shared/scenes/spd-teapot/view.json
# BUILD_AB_EMBREE=1: each process builds as run_shared_scenes.sh's table does, taking turns with
# Embree's two builds (--compare-embree --isa avx512 --reps 5, no --build-reps: builds until
# rtc's add up to half a second, at most 100; BUILDS is then unused), so that each rtc build
# starts with the caches Embree's builds left.
set -euo pipefail
[ $# -ge 6 ] || { echo "usage: $0 BIN_A BIN_B ROUNDS THREADS BUILDS VIEW..." >&2; exit 2; }
bin_a=$1
bin_b=$2
rounds=$3
threads=$4
builds=$5
shift 5
for b in "$bin_a" "$bin_b"; do
  [ -x "$b" ] || { echo "run_build_ab: $b is not an executable" >&2; exit 1; }
done
for n in "$rounds" "$threads" "$builds"; do
  [[ "$n" =~ ^[1-9][0-9]*$ ]] || { echo "run_build_ab: '$n' is not a positive count" >&2; exit 2; }
done
build_ms() {
  local args=(--reps 1 --build-reps "$builds")
  [ "${BUILD_AB_EMBREE:-0}" = 1 ] && args=(--reps 5 --compare-embree --isa avx512)
  "$1" "$2" --threads "$threads" "${args[@]}" --mode primary --json |
    python3 -c "import json, sys; print(json.loads(sys.stdin.readline())['build_ms'])"
}
for view in "$@"; do
  [ -f "$view" ] || { echo "run_build_ab: $view is not a file" >&2; exit 1; }
  a=()
  b=()
  for ((r = 0; r < rounds; ++r)); do
    a+=("$(build_ms "$bin_a" "$view")")
    b+=("$(build_ms "$bin_b" "$view")")
  done
  python3 - "$view" "$threads" "${a[*]}" "${b[*]}" <<'PY'
import statistics
import sys

view, threads = sys.argv[1], sys.argv[2]
a = [float(x) for x in sys.argv[3].split()]
b = [float(x) for x in sys.argv[4].split()]
ratios = [y / x for x, y in zip(a, b) if x > 0]
fmt = lambda v: ", ".join(f"{x:.3f}" for x in v)
print(f"{view} ({threads} threads) build ms A: {fmt(a)}")
print(f"{view} ({threads} threads) build ms B: {fmt(b)}")
if ratios:
    print(f"{view}: B / A median {statistics.median(ratios):.3f} ({min(ratios):.3f}-{max(ratios):.3f})")
PY
done
