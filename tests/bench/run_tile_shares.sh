#!/usr/bin/env bash
# rtc's primary rays against Embree's best mode on parts of the image of different sizes, beside
# the part of rtc's tree those rays read (its footprint): how the ratio depends on which side's
# working set the caches hold. Each part is a share of the image's 16x16 tiles in rows from the
# top (rtc-bench --tiles), traced by every side alike, at 1 and 2 threads; the footprint (the
# distinct 64-byte lines of kd nodes and leaf slots one pass reads) comes from the stats preset
# (build/stats), built or brought up to date here like build/release.
# Usage: tests/bench/run_tile_shares.sh [SCENES_DIR] [NAME] [REPS] [SHARES]
#   SCENES_DIR (relative to the repository root) may be a folder of links to some views of the pack.
#   SHARES: space-separated FROM:TO (default: the whole image, its halves, two eighths, two 3% strips).
# Writes tests/bench/results/NAME.jsonl and NAME.md (default NAME: tile_shares; REPS: 9); the
# previous ones stay until both new ones are whole.
set -euo pipefail
cd "$(dirname "$0")/../.."
scenes=${1:-../shared/scenes}
name=${2:-tile_shares}
reps=${3:-9}
shares=${4:-"0:1 0:0.5 0.5:1 0.125:0.25 0.5:0.625 0.2:0.23 0.5:0.53"}
[ -d "$scenes" ] || { echo "run_tile_shares: $scenes is not a folder (the shared scene pack)" >&2; exit 1; }
mapfile -t views < <(find -L "$scenes" -name 'view*.json' | sort)
[ "${#views[@]}" -gt 0 ] || { echo "run_tile_shares: no view*.json under $scenes" >&2; exit 1; }
for preset in release stats; do
  [ -d "build/$preset" ] || cmake --preset "$preset" >/dev/null
  cmake --build --preset "$preset" --target rtc-bench
done
out=tests/bench/results
mkdir -p "$out"
jsonl=$out/$name.jsonl
: > "$jsonl.tmp"
for view in "${views[@]}"; do
  for share in $shares; do
    echo "rtc-bench $view --tiles $share" >&2
    build/stats/tests/bench/rtc-bench "$view" --threads 1 --reps 1 --build-reps 1 --mode primary --tiles "$share" \
      --json >> "$jsonl.tmp"
    for threads in 1 2; do
      build/release/tests/bench/rtc-bench "$view" --threads "$threads" --reps "$reps" --build-reps 1 --mode primary \
        --compare-embree --tiles "$share" --json >> "$jsonl.tmp"
    done
  done
done
python3 tests/bench/summarize_tile_shares.py "$jsonl.tmp" > "$out/$name.md.tmp"
mv "$jsonl.tmp" "$jsonl"
mv "$out/$name.md.tmp" "$out/$name.md"
echo "wrote $jsonl and $out/$name.md" >&2
