#!/usr/bin/env bash
# Regenerates the time/error results under tests/bench/results/sweep/: a full rtc-bench --sweep
# (every setting, 3 reps) of the README's scene with its plot, and a quick sweep (a few settings
# per group) of every other view of the shared scene pack; then the summary table sweeps.md.
# Usage: tests/bench/run_sweeps.sh [SCENES_DIR] [README_SCENE]
set -euo pipefail
cd "$(dirname "$0")/../.."
scenes=${1:-../shared/scenes}
main_scene=${2:-spd-balls-s3}
bench=build/release/tests/bench/rtc-bench
[ -d "$scenes" ] || { echo "run_sweeps: $scenes is not a folder (the shared scene pack)" >&2; exit 1; }
[ -x "$bench" ] || { cmake --preset release >/dev/null && cmake --build --preset release --target rtc-bench; }
out=tests/bench/results/sweep
mkdir -p "$out"
for view in $(find -L "$scenes" -name 'view*.json' | sort); do
  name=$(basename "$(dirname "$view")")
  case $(basename "$view") in view-*.json) name=$(basename "$view" .json); name=${name#view-} ;; esac
  args=(--sweep "$out/$name")
  [ "$name" = "$main_scene" ] || args+=(--sweep-quick)
  echo "rtc-bench $view ${args[*]}" >&2
  "$bench" "$view" "${args[@]}" > "$out/$name.log"
  python3 tests/bench/plot_sweep.py "$out/$name/sweep.csv" "$out/$name/plot.png" --title "rtc time against error: $name"
  rm -f "$out/$name"/*.exr  # large; rtc-bench writes them again on a rerun
done
python3 tests/bench/summarize_sweeps.py "$out" > "$out/sweeps.md"
echo "wrote $out/sweeps.md" >&2
