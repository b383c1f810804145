#!/usr/bin/env bash
# SAH traversal cost K_T against build time (tests/bench/run_kd_ab.sh with --kd-traversal-cost):
# writes tests/bench/results/kd_cost.txt and kd_cost.md.
# Usage: tests/bench/run_kd_cost.sh [SCENES_DIR] [ROUNDS] [K_T values, default "2 3"]
set -euo pipefail
cd "$(dirname "$0")/../.."
exec tests/bench/run_kd_ab.sh --kd-traversal-cost "${3:-2 3}" kd_cost "${1:-../shared/scenes}" "${2:-3}"
