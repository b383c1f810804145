#!/usr/bin/env bash
# Builds the libFuzzer targets (preset "fuzz": clang 14, ASan + UBSan) and runs each one for a
# bounded time on a copy of its seed corpus (tests/fuzz/corpus/<target>), two at a time. Prints
# a table (executions, exec/s, corpus growth, coverage) and writes it to build/fuzz/summary.md.
# An input that crashes a target, trips a sanitizer, breaks a property the target checks or
# times out is copied to tests/fuzz/regressions/<target>/ (ctest's Fuzz.<target> replays it
# from then on) and the script exits 1.
# Usage: [RTC_FUZZ_SEED=N] [RTC_FUZZ_JOBS=2] tests/fuzz/run_fuzz.sh [SECONDS per target, default 60] [TARGET ...]
#   RTC_FUZZ_SEED: libFuzzer's -seed (default 0: a new random seed each run; CI passes 1 so that
#   its run is the same each time)
set -euo pipefail
cd "$(dirname "$0")/../.."
seconds=${1:-60}
shift $(( $# > 0 ? 1 : 0 ))
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=(protocol scene_bytes tile_pixels obj ply nff gltf scene_json)
jobs=${RTC_FUZZ_JOBS:-2}
seed=${RTC_FUZZ_SEED:-0}

cmake --preset fuzz >/dev/null
cmake --build --preset fuzz
bin=build/fuzz/tests/fuzz
# Loaders read files: keep the scratch files in memory where /dev/shm is there.
work=$(mktemp -d -p /dev/shm 2>/dev/null || mktemp -d)
trap 'rm -rf "$work"' EXIT

run_one() {
  local t=$1 dir=$work/$1
  mkdir -p "$dir/corpus" "$dir/artifacts"
  cp tests/fuzz/corpus/"$t"/* "$dir/corpus/"
  local seeds
  seeds=$(ls "$dir/corpus" | wc -l)
  # -timeout: one input taking 10 s is a hang; -rss_limit_mb: 2 GiB is a runaway allocation.
  # TMPDIR: the loaders' scratch files stay in this run's folder.
  set +e
  TMPDIR=$dir "$bin/fuzz_$t" "$dir/corpus" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
    -seed="$seed" -print_final_stats=1 -artifact_prefix="$dir/artifacts/" >"$dir/log" 2>&1
  local rc=$?
  set -e
  local execs rate cov found
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$dir/log" | tail -1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$dir/log" | tail -1)
  cov=$(grep -ao 'cov: [0-9]*' "$dir/log" | tail -1 | cut -d' ' -f2)
  found=$(ls "$dir/artifacts" | wc -l)
  echo "| $t | $seconds | ${execs:-?} | ${rate:-?} | $seeds -> $(ls "$dir/corpus" | wc -l) | ${cov:-?} | $found |" >"$dir/row"
  echo "$rc" >"$dir/rc"
}

echo "fuzzing ${targets[*]} for ${seconds} s each, $jobs at a time, seed $seed" >&2
running=0
for t in "${targets[@]}"; do
  [ -x "$bin/fuzz_$t" ] || { echo "run_fuzz: no target $t" >&2; exit 2; }
  run_one "$t" &
  running=$((running + 1))
  if [ "$running" -ge "$jobs" ]; then wait -n; running=$((running - 1)); fi
done
wait

summary=build/fuzz/summary.md
{
  echo "| target | s | executions | exec/s | corpus (seeds -> kept) | coverage (edges) | findings |"
  echo "|---|---:|---:|---:|---|---:|---:|"
  for t in "${targets[@]}"; do cat "$work/$t/row"; done
} >"$summary"
cat "$summary"

failed=0
for t in "${targets[@]}"; do
  rc=$(cat "$work/$t/rc")
  if [ "$rc" != 0 ] || [ -n "$(ls "$work/$t/artifacts")" ]; then
    failed=1
    mkdir -p tests/fuzz/regressions/"$t"
    for a in "$work/$t"/artifacts/*; do
      [ -e "$a" ] && cp "$a" tests/fuzz/regressions/"$t"/
    done
    echo "run_fuzz: $t FAILED (exit $rc); inputs kept in tests/fuzz/regressions/$t/; the end of its log:" >&2
    tail -40 "$work/$t/log" >&2
  fi
done
exit "$failed"
