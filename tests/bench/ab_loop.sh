#!/usr/bin/env bash
# The loop shared by run_kd_ab.sh and run_bin_ab.sh: two variants A and B (each an rtc-bench
# binary with extra arguments) on every view of the scene pack, one thread, the widest packets
# the CPU has (rtc-bench's default ISA; AB_ISA below), process CPU time, alternating view by
# view, ROUNDS times. Writes tests/bench/results/NAME.txt (one line per view, label, round and
# mode: scene label round mode Mrays/s build_ms nodes SAH triangles isa; primary and shadow runs
# add a line for the same rays traced one at a time, mode primary-single / shadow-single) and
# NAME.md (tests/bench/summarize_kd_ab.py WHAT).
# Usage: tests/bench/ab_loop.sh NAME SCENES_DIR ROUNDS WHAT LABEL_A BIN_A "ARGS_A" LABEL_B BIN_B "ARGS_B"
# AB_MODES: the rtc-bench modes to time (default "primary shadow"; e.g. "full" for whole frames).
# AB_ISA: the kernel ISA, sse4, avx2 or avx512 (default: rtc-bench's, the widest the CPU runs).
set -euo pipefail
cd "$(dirname "$0")/../.."
[ $# -eq 10 ] || { echo "usage: $0 NAME SCENES_DIR ROUNDS WHAT LABEL_A BIN_A ARGS_A LABEL_B BIN_B ARGS_B" >&2; exit 2; }
name=$1 scenes=$2 rounds=$3 what=$4
labels=("$5" "$8") bins=("$6" "$9") args=("$7" "${10}")
isa_args=${AB_ISA:+--isa $AB_ISA}
mode_args=""
for m in ${AB_MODES:-primary shadow}; do mode_args="$mode_args --mode $m"; done
out=tests/bench/results
mkdir -p "$out"
: > "$out/$name.txt.tmp"
views=$(find -L "$scenes" -name 'view*.json' | sort)
for r in $(seq "$rounds"); do
  for view in $views; do
    for k in 0 1; do
      v=${labels[$k]}
      echo "${bins[$k]} $view ${args[$k]} ($v, round $r of $rounds)" >&2
      # shellcheck disable=SC2086  # the extra arguments are words
      # shellcheck disable=SC2086
      "${bins[$k]}" "$view" --threads 1 --reps 5 --build-reps 3 $mode_args $isa_args \
        --cpu-time --json ${args[$k]} |
        python3 -c "
import json, sys
for line in sys.stdin:
    j = json.loads(line)
    print(j['scene'], '$v', '$r', j['mode'], round(j['mrays_per_s'], 3), round(j['build_ms'], 1), j['kd_nodes'],
          round(j['kd_sah_cost'], 2), j['triangles'], j['isa'])
    if 'mrays_per_s_single' in j:  # the same rays one at a time (N=1 traversal)
        print(j['scene'], '$v', '$r', j['mode'] + '-single', round(j['mrays_per_s_single'], 3), round(j['build_ms'], 1),
              j['kd_nodes'], round(j['kd_sah_cost'], 2), j['triangles'], j['isa'])" >> "$out/$name.txt.tmp"
    done
  done
done
mv "$out/$name.txt.tmp" "$out/$name.txt"
python3 tests/bench/summarize_kd_ab.py "$out/$name.txt" "$what" "$name" > "$out/$name.md"
echo "wrote $out/$name.txt and $out/$name.md" >&2
