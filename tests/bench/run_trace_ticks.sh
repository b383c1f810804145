#!/usr/bin/env bash
# Where each view's Whitted frame spends its tracing time, rtc against the Embree renderer: the
# renderer's trace calls timed by kind (primary rays, mirror rays, each light's shadow rays) and by
# how many of a packet's lanes carry a ray, one thread, the best ISA. Builds the ticks preset
# (RTC_TRACE_TICKS: the trace calls read the time stamp counter, about 100 ticks a call on both
# sides) into build/ticks, or brings it up to date.
# Usage: tests/bench/run_trace_ticks.sh [SCENES_DIR] [NAME] [REPS]
#   SCENES_DIR (relative to the repository root) may be a folder of links to some views of the pack.
# Writes tests/bench/results/NAME.jsonl and NAME.md (default NAME: trace_ticks; REPS: 9 frames);
# the previous ones stay until both new ones are whole.
set -euo pipefail
cd "$(dirname "$0")/../.."
scenes=${1:-../shared/scenes}
name=${2:-trace_ticks}
reps=${3:-9}
bench=build/ticks/tests/bench/rtc-bench
[ -d "$scenes" ] || { echo "run_trace_ticks: $scenes is not a folder (the shared scene pack)" >&2; exit 1; }
mapfile -t views < <(find -L "$scenes" -name 'view*.json' | sort)
[ "${#views[@]}" -gt 0 ] || { echo "run_trace_ticks: no view*.json under $scenes" >&2; exit 1; }
[ -d build/ticks ] || cmake --preset ticks >/dev/null
cmake --build --preset ticks --target rtc-bench
out=tests/bench/results
mkdir -p "$out"
jsonl=$out/$name.jsonl
: > "$jsonl.tmp"
for view in "${views[@]}"; do
  echo "rtc-bench (ticks build) $view" >&2
  "$bench" "$view" --threads 1 --reps "$reps" --build-reps 1 --mode full --compare-embree --json >> "$jsonl.tmp"
done
python3 tests/bench/summarize_trace_ticks.py "$jsonl.tmp" > "$out/$name.md.tmp"
mv "$jsonl.tmp" "$jsonl"
mv "$out/$name.md.tmp" "$out/$name.md"
echo "wrote $jsonl and $out/$name.md" >&2
