#!/usr/bin/env bash
# Regenerates tests/bench/results/: rtc-bench --compare-embree on every view of the shared scene
# pack, with 1 and 2 threads, as JSON lines plus a Markdown summary.
# Usage: tests/bench/run_shared_scenes.sh [SCENES_DIR] [REPS] [NAME] [RUNS]
# RUNS (default 3): sweeps over all views, one after another; each line records its run, and the
# tables give per figure the median over the runs (each run's figure the median over REPS), with
# the runs' range of the ratios to Embree, since on a shared VM one process's figures can be off
# by 30% where the next one's are not.
# NAME: the results' file name (default shared_scenes: the AVX-512 machine's table;
# shared_scenes_avx2 holds one taken on an AVX2 machine without AVX-512)
# RTC_BENCH: the rtc-bench binary (default build/release/tests/bench/rtc-bench)
set -euo pipefail
cd "$(dirname "$0")/../.."
scenes=${1:-../shared/scenes}
reps=${2:-5}
name=${3:-shared_scenes}
runs=${4:-3}
bench=${RTC_BENCH:-build/release/tests/bench/rtc-bench}
[ -d "$scenes" ] || { echo "run_shared_scenes: $scenes is not a folder (the shared scene pack)" >&2; exit 1; }
[[ "$runs" =~ ^[1-9][0-9]*$ ]] || { echo "run_shared_scenes: RUNS must be a positive whole number, not '$runs'" >&2; exit 2; }
[ -x "$bench" ] || { cmake --preset release >/dev/null && cmake --build --preset release --target rtc-bench; }
out=tests/bench/results
mkdir -p "$out"
jsonl=$out/$name.jsonl
: > "$jsonl.tmp"
views=$(find -L "$scenes" -name 'view*.json' | sort)
for run in $(seq "$runs"); do
  for view in $views; do
    for threads in 1 2; do
      echo "run $run of $runs: rtc-bench $view --threads $threads" >&2
      "$bench" "$view" --threads "$threads" --reps "$reps" --compare-embree --json | sed "s/^{/{\"run\":$run,/" >> "$jsonl.tmp"
    done
  done
done
mv "$jsonl.tmp" "$jsonl"
python3 tests/bench/summarize.py "$jsonl" > "$out/$name.md"
echo "wrote $jsonl and $out/$name.md" >&2
