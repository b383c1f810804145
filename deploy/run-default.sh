#!/usr/bin/env bash
# The main job on a fresh machine: installs what is missing, builds, and renders a frame of the
# built-in default scene with rtc-render, printing where it went.
# Usage: ./deploy/run-default.sh [extra rtc-render args, e.g. --frames 0-23]
set -euo pipefail
cd "$(dirname "$0")/.."
./deploy/install-deps.sh
cmake --preset release
cmake --build --preset release --target rtc-render
./build/release/worker/rtc-render --frames 0 "$@"
