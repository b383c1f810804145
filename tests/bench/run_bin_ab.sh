#!/usr/bin/env bash
# Two rtc-bench binaries against each other (a code change, before and after): every view of the
# shared scene pack, one thread, 16-wide packets (avx512), process CPU time, the binaries
# alternating view by view, ROUNDS times. Writes tests/bench/results/NAME.txt (lines as
# run_kd_ab.sh's, with A and B for the value) and NAME.md (tests/bench/summarize_kd_ab.py: ratios
# B over A, paired round by round).
# Usage: tests/bench/run_bin_ab.sh BIN_A BIN_B NAME [SCENES_DIR] [ROUNDS]
#   e.g. cp build/release/tests/bench/rtc-bench /tmp/before; (change, rebuild);
#        tests/bench/run_bin_ab.sh /tmp/before build/release/tests/bench/rtc-bench leaf_records
set -euo pipefail
cd "$(dirname "$0")/../.."
[ $# -ge 3 ] || { echo "usage: $0 BIN_A BIN_B NAME [SCENES_DIR] [ROUNDS]" >&2; exit 2; }
bin_a=$1
bin_b=$2
name=$3
scenes=${4:-../shared/scenes}
rounds=${5:-3}
for b in "$bin_a" "$bin_b"; do
  [ -x "$b" ] || { echo "run_bin_ab: $b is not an executable" >&2; exit 1; }
done
[ -d "$scenes" ] || { echo "run_bin_ab: $scenes is not a folder (the shared scene pack)" >&2; exit 1; }
out=tests/bench/results
mkdir -p "$out"
: > "$out/$name.txt.tmp"
views=$(find "$scenes" -name 'view*.json' | sort)
for r in $(seq "$rounds"); do
  for view in $views; do
    for v in A B; do
      bin=$bin_a
      [ "$v" = B ] && bin=$bin_b
      echo "$bin $view (binary $v, round $r of $rounds)" >&2
      "$bin" "$view" --threads 1 --reps 5 --build-reps 3 --mode primary --mode shadow --isa avx512 --cpu-time --json |
        python3 -c "
import json, sys
for line in sys.stdin:
    j = json.loads(line)
    print(j['scene'], '$v', '$r', j['mode'], round(j['mrays_per_s'], 3), round(j['build_ms'], 1), j['kd_nodes'],
          round(j['kd_sah_cost'], 2), j['triangles'])" >> "$out/$name.txt.tmp"
    done
  done
done
mv "$out/$name.txt.tmp" "$out/$name.txt"
python3 tests/bench/summarize_kd_ab.py "$out/$name.txt" binaries "$name" > "$out/$name.md"
echo "wrote $out/$name.txt and $out/$name.md" >&2
