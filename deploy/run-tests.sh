#!/usr/bin/env bash
# Installs what is missing, builds the release preset and runs the whole test suite (ctest).
# Usage: ./deploy/run-tests.sh [extra ctest args, e.g. -L unit]
set -euo pipefail
cd "$(dirname "$0")/.."
./deploy/install-deps.sh
cmake --preset release
cmake --build --preset release
ctest --preset release "$@"
