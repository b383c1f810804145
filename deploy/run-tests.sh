#!/usr/bin/env bash
# Installs what is missing, builds the release preset and runs the whole test suite (ctest), then
# the fuzz targets for 30 s each (tests/fuzz/run_fuzz.sh).
# Usage: [RTC_FUZZ_SECONDS=30] ./deploy/run-tests.sh [extra ctest args, e.g. -L unit: no fuzz run]
set -euo pipefail
cd "$(dirname "$0")/.."
./deploy/install-deps.sh
cmake --preset release
cmake --build --preset release
ctest --preset release "$@"
# After the whole suite: every fuzz target for a bounded time (clang, ASan + UBSan; seed 1 so that
# CI runs the same inputs each time). RTC_FUZZ_SECONDS=0 skips it.
fuzz_seconds=${RTC_FUZZ_SECONDS:-30}
if [ $# -eq 0 ] && [ "$fuzz_seconds" != 0 ]; then
  RTC_FUZZ_SEED=${RTC_FUZZ_SEED:-1} tests/fuzz/run_fuzz.sh "$fuzz_seconds"
fi
