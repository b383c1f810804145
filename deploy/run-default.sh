#!/usr/bin/env bash
# The main job on a fresh machine: installs what is missing, builds, and renders the built-in
# default scene's animation on a local cluster (rtc-master + one rtc-worker per core, over
# loopback), printing the frame-rate log; frames go to out/cluster/default_####.png.
# Usage: ./deploy/run-default.sh [N workers] [-- extra rtc-master args, e.g. --frames 0-9]
set -euo pipefail
cd "$(dirname "$0")/.."
./deploy/install-deps.sh
cmake --preset release
cmake --build --preset release --target rtc-master rtc-worker rtc-render
exec ./deploy/launch-local.sh "$@"
