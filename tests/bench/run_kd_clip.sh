#!/usr/bin/env bash
# Regenerates tests/bench/results/kd_clip.md: the kd-tree with and without perfect splits
# (KdBuildOptions::clip, `--kd-clip on|off`) on every view of the shared scene pack: build time,
# tree size and SAH cost against primary, shadow and full-frame speed, and the number of
# frames after which the slower build has paid for itself. The two builds of a view run back to
# back, alternating, REPEAT times; figures are medians of the runs' medians. Times are process
# CPU time (rtc-bench --cpu-time), which other work on the machine disturbs far less than the
# wall clock; with THREADS > 1 they are summed over the threads.
# Usage: tests/bench/run_kd_clip.sh [SCENES_DIR] [THREADS] [REPEAT] [REPS]
set -euo pipefail
cd "$(dirname "$0")/../.."
scenes=${1:-../shared/scenes}
threads=${2:-1}
repeat=${3:-2}
reps=${4:-3}
bench=build/release/tests/bench/rtc-bench
[ -d "$scenes" ] || { echo "run_kd_clip: $scenes is not a folder (the shared scene pack)" >&2; exit 1; }
[ -x "$bench" ] || { cmake --preset release >/dev/null && cmake --build --preset release --target rtc-bench; }
out=tests/bench/results
mkdir -p "$out"
jsonl=$out/kd_clip.jsonl
: > "$jsonl.tmp"
views=$(find -L "$scenes" -name 'view*.json' | sort)
for view in $views; do
  for r in $(seq 1 "$repeat"); do
    for clip in off on; do
      echo "rtc-bench $view --kd-clip $clip --threads $threads (run $r of $repeat)" >&2
      "$bench" "$view" --kd-clip "$clip" --threads "$threads" --reps "$reps" --cpu-time --json >> "$jsonl.tmp"
    done
  done
done
mv "$jsonl.tmp" "$jsonl"
python3 tests/bench/summarize_kd_clip.py "$jsonl" > "$out/kd_clip.md"
echo "wrote $jsonl and $out/kd_clip.md" >&2
