#!/usr/bin/env bash
# The main job on a fresh machine: installs what is missing, builds, and renders the built-in
# default scene's animation on a local cluster (rtc-master + one rtc-worker per core, over
# loopback), printing the frame-rate log; frames go to out/cluster/default_####.png.
# Usage: ./deploy/run-default.sh [N workers] [SCENE] [-- extra rtc-master args, e.g. --frames 0-9]
set -euo pipefail
cd "$(dirname "$0")/.."
# Only what the three programs need (no test, benchmark or deployment tools: ./deploy/run-tests.sh
# installs those), built by the `programs` preset into build/programs.
./deploy/install-deps.sh --build-only
cmake --preset programs
cmake --build --preset programs
RTC_BUILD_DIR="$PWD/build/programs" exec ./deploy/launch-local.sh "$@"
