#!/usr/bin/env bash
# Regenerates tests/bench/results/: rtc-bench --compare-embree on every view of the shared scene
# pack, with 1 and 2 threads, as JSON lines plus a Markdown summary.
# Usage: tests/bench/run_shared_scenes.sh [SCENES_DIR] [REPS] [NAME]
# NAME: the results' file name (default shared_scenes: the AVX-512 machine's table;
# shared_scenes_avx2 holds one taken on an AVX2 machine without AVX-512)
# RTC_BENCH: the rtc-bench binary (default build/release/tests/bench/rtc-bench)
set -euo pipefail
cd "$(dirname "$0")/../.."
scenes=${1:-../shared/scenes}
reps=${2:-5}
name=${3:-shared_scenes}
bench=${RTC_BENCH:-build/release/tests/bench/rtc-bench}
[ -d "$scenes" ] || { echo "run_shared_scenes: $scenes is not a folder (the shared scene pack)" >&2; exit 1; }
[ -x "$bench" ] || { cmake --preset release >/dev/null && cmake --build --preset release --target rtc-bench; }
out=tests/bench/results
mkdir -p "$out"
jsonl=$out/$name.jsonl
: > "$jsonl.tmp"
views=$(find "$scenes" -name 'view*.json' | sort)
for view in $views; do
  for threads in 1 2; do
    echo "rtc-bench $view --threads $threads" >&2
    "$bench" "$view" --threads "$threads" --reps "$reps" --compare-embree --json >> "$jsonl.tmp"
  done
done
mv "$jsonl.tmp" "$jsonl"
python3 tests/bench/summarize.py "$jsonl" > "$out/$name.md"
echo "wrote $jsonl and $out/$name.md" >&2
