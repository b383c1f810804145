#!/usr/bin/env bash
# Two rtc-bench binaries against each other (a code change, before and after): every view of the
# shared scene pack, one thread, the widest packets the CPU has (16-wide on AVX-512; AB_ISA=avx2
# or sse4 picks another), process CPU time, the binaries alternating view by view, ROUNDS times.
# Writes tests/bench/results/NAME.txt (lines as run_kd_ab.sh's, with A and B for the value) and
# NAME.md (tests/bench/summarize_kd_ab.py: ratios B over A, paired round by round).
# Usage: tests/bench/run_bin_ab.sh BIN_A BIN_B NAME [SCENES_DIR] [ROUNDS]
#   AB_MODES="full" (or "primary shadow full") times whole Whitted frames too (ab_loop.sh).
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
exec tests/bench/ab_loop.sh "$name" "$scenes" "$rounds" binaries A "$bin_a" "" B "$bin_b" ""
