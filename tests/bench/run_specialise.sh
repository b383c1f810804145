#!/usr/bin/env bash
# Regenerates tests/bench/results/specialise.md: kernels specialised to each scene's features
# against the general kernel, each with and without empty-space skipping (issue 7, parts 1 and
# 2), on the built-in scene (and variants of it that the specialised kernels serve: no lights,
# no mirrors, neither, without depth and normal channels) and every view of the shared scene
# pack. Each run of rtc-bench --kernel-ab renders the four kernels in turn AB_REPS times on one
# prepared frame and checks that they give the same pixels; figures are the medians of the
# paired ratios (each kernel's time over the general one's in the same repetition), then the
# median over REPEAT runs. Times are process CPU time on THREADS threads (rtc-bench --cpu-time).
# Usage: tests/bench/run_specialise.sh [SCENES_DIR] [REPEAT] [AB_REPS] [THREADS]
set -euo pipefail
cd "$(dirname "$0")/../.."
scenes=${1:-../shared/scenes}
repeat=${2:-3}
ab_reps=${3:-15}
threads=${4:-1}
bench=build/release/tests/bench/rtc-bench
[ -x "$bench" ] || { cmake --preset release >/dev/null && cmake --build --preset release --target rtc-bench; }
out=tests/bench/results
mkdir -p "$out"
jsonl=$out/specialise.jsonl
: > "$jsonl.tmp"
run() {  # label, rtc-bench arguments
  local label=$1
  shift
  for r in $(seq 1 "$repeat"); do
    echo "rtc-bench $* (run $r of $repeat)" >&2
    "$bench" "$@" --mode full --kernel-ab --threads "$threads" --reps 1 --ab-reps "$ab_reps" --cpu-time --json \
      --log-level error | python3 -c "import json, sys; r = json.loads(sys.stdin.read()); r['label'] = '$label'; print(json.dumps(r))" \
      >> "$jsonl.tmp"
  done
}
run "default" ""
run "default, no lights" "" --no-lights
run "default, no mirrors" "" --no-mirrors
run "default, no lights or mirrors" "" --no-lights --no-mirrors
run "default, no lights or mirrors, no AOVs" "" --no-lights --no-mirrors --no-aovs
run "default, no AOVs" "" --no-aovs
if [ -d "$scenes" ]; then
  for view in $(find -L "$scenes" -name 'view*.json' | sort); do
    run "$(basename "$(dirname "$view")")/$(basename "$view")" "$view"
  done
else
  echo "run_specialise: $scenes is not a folder (the shared scene pack): built-in scene only" >&2
fi
mv "$jsonl.tmp" "$jsonl"
python3 tests/bench/summarize_specialise.py "$jsonl" > "$out/specialise.md"
echo "wrote $jsonl and $out/specialise.md" >&2
