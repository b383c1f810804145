#!/usr/bin/env bash
# SAH traversal cost K_T against build time: rtc-bench on every view of the shared scene pack with
# each K_T given, one thread, 16-wide packets (avx512), process CPU time, the K_T values
# alternating view by view, ROUNDS times. Writes tests/bench/results/kd_cost.txt (one line per
# view, K_T, round and mode: scene K_T round mode Mrays/s build_ms nodes SAH triangles) and
# kd_cost.md (tests/bench/summarize_kd_cost.py: per view the median ratio of the K_T values'
# throughputs, paired round by round, and their build times).
# Usage: tests/bench/run_kd_cost.sh [SCENES_DIR] [ROUNDS] [K_T values, default "2 3"]
set -euo pipefail
cd "$(dirname "$0")/../.."
scenes=${1:-../shared/scenes}
rounds=${2:-3}
values=${3:-2 3}
bench=build/release/tests/bench/rtc-bench
[ -d "$scenes" ] || { echo "run_kd_cost: $scenes is not a folder (the shared scene pack)" >&2; exit 1; }
[ -x "$bench" ] || { cmake --preset release >/dev/null && cmake --build --preset release --target rtc-bench; }
out=tests/bench/results
mkdir -p "$out"
: > "$out/kd_cost.txt.tmp"
views=$(find "$scenes" -name 'view*.json' | sort)
for r in $(seq "$rounds"); do
  for view in $views; do
    for kt in $values; do
      echo "rtc-bench $view --kd-traversal-cost $kt (round $r of $rounds)" >&2
      "$bench" "$view" --threads 1 --reps 5 --build-reps 3 --mode primary --mode shadow --isa avx512 --cpu-time \
        --json --kd-traversal-cost "$kt" |
        python3 -c "
import json, sys
for line in sys.stdin:
    j = json.loads(line)
    print(j['scene'], '$kt', '$r', j['mode'], round(j['mrays_per_s'], 3), round(j['build_ms'], 1), j['kd_nodes'],
          round(j['kd_sah_cost'], 2), j['triangles'])" >> "$out/kd_cost.txt.tmp"
    done
  done
done
mv "$out/kd_cost.txt.tmp" "$out/kd_cost.txt"
python3 tests/bench/summarize_kd_cost.py "$out/kd_cost.txt" > "$out/kd_cost.md"
echo "wrote $out/kd_cost.txt and $out/kd_cost.md" >&2
