#!/usr/bin/env bash
# What the kd-tree walks do on every view of the shared scene pack: per walk of a packet and of a
# single ray, inner-node steps, leaves entered, triangle tests and the lanes live in them, for
# primary rays and for shadow rays walked from either end, one thread, the best ISA. Builds the
# stats preset (RTC_WALK_STATS: counting walks, so its timings are not the tracer's) into
# build/stats if it is not there.
# Usage: tests/bench/run_walk_stats.sh [SCENES_DIR] [NAME]
# Writes tests/bench/results/NAME.jsonl and NAME.md (default NAME: walk_stats).
set -euo pipefail
cd "$(dirname "$0")/../.."
scenes=${1:-../shared/scenes}
name=${2:-walk_stats}
bench=build/stats/tests/bench/rtc-bench
[ -d "$scenes" ] || { echo "run_walk_stats: $scenes is not a folder (the shared scene pack)" >&2; exit 1; }
if [ ! -x "$bench" ]; then
  cmake --preset stats >/dev/null
  cmake --build --preset stats --target rtc-bench
fi
out=tests/bench/results
mkdir -p "$out"
jsonl=$out/$name.jsonl
: > "$jsonl.tmp"
for view in $(find -L "$scenes" -name 'view*.json' | sort); do
  echo "rtc-bench (stats build) $view" >&2
  # Shadow rays from either end, each order fixed: auto picks by timings, so its counts vary.
  "$bench" "$view" --threads 1 --reps 1 --mode primary --mode shadow --shadow-order near --json >> "$jsonl.tmp"
  "$bench" "$view" --threads 1 --reps 1 --build-reps 1 --mode shadow --shadow-order far --json >> "$jsonl.tmp"
done
mv "$jsonl.tmp" "$jsonl"
python3 tests/bench/summarize_walk_stats.py "$jsonl" > "$out/$name.md"
echo "wrote $jsonl and $out/$name.md" >&2
