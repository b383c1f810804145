#!/usr/bin/env bash
# Two rtc-bench binaries' first builds, as a worker builds its tree: each run is a fresh process
# that loads the view, builds once and traces primary rays, after IDLE seconds with nothing
# running. (On a VM with free page reporting memory idle for a few seconds is handed back to
# the host, and the first touches of a build's fresh pages then cost several times more than
# in a process that builds again; the median of repeated builds in one process does not show
# that.) The binaries alternate view by view, ROUNDS times.
# Usage: tests/bench/run_first_builds.sh BIN_A BIN_B NAME [SCENES_DIR] [ROUNDS]
#   THREADS (default 2), IDLE (seconds before each run, default 6), VIEWS (names of scene
#   folders, default the four largest: spd-tree spd-mount-s10 spd-balls spd-rings),
#   ARGS_A / ARGS_B (more rtc-bench options for either binary).
# Writes tests/bench/results/NAME.txt (view, binary, round, build ms, primary M rays/s) and
# NAME.md (per view the runs and their medians, and B's median over A's).
set -euo pipefail
cd "$(dirname "$0")/../.."
[ $# -ge 3 ] || { echo "usage: $0 BIN_A BIN_B NAME [SCENES_DIR] [ROUNDS]" >&2; exit 2; }
bins=("$1" "$2")
name=$3
scenes=${4:-../shared/scenes}
rounds=${5:-4}
threads=${THREADS:-2}
idle=${IDLE:-6}
views=${VIEWS:-spd-tree spd-mount-s10 spd-balls spd-rings}
args=("${ARGS_A:-}" "${ARGS_B:-}")
labels=(A B)
for b in "${bins[@]}"; do
  [ -x "$b" ] || { echo "run_first_builds: $b is not an executable" >&2; exit 1; }
done
for v in $views; do
  [ -f "$scenes/$v/view.json" ] || { echo "run_first_builds: no $scenes/$v/view.json" >&2; exit 1; }
done
out=tests/bench/results
mkdir -p "$out"
: > "$out/$name.txt.tmp"
for r in $(seq "$rounds"); do
  for v in $views; do
    for k in 0 1; do
      echo "${bins[$k]} $v ${args[$k]} (${labels[$k]}, round $r of $rounds, after ${idle} s idle)" >&2
      sleep "$idle"
      # shellcheck disable=SC2086  # ARGS_A / ARGS_B are option lists
      "${bins[$k]}" "$scenes/$v/view.json" --threads "$threads" --reps 5 --build-reps 1 --mode primary --json \
        ${args[$k]} | python3 -c "
import json, sys
for line in sys.stdin:
    j = json.loads(line)
    print('$v', '${labels[$k]}', '$r', round(j['build_ms'], 1), round(j['mrays_per_s'], 3))" >> "$out/$name.txt.tmp"
    done
  done
done
mv "$out/$name.txt.tmp" "$out/$name.txt"
python3 - "$out/$name.txt" "$name" "$threads" "$idle" "${bins[0]}" "${bins[1]}" "${args[0]}" "${args[1]}" \
  > "$out/$name.md" <<'EOF'
import collections
import statistics
import sys

path, name, threads, idle, bin_a, bin_b, args_a, args_b = sys.argv[1:]
runs = collections.defaultdict(list)
views = []
for line in open(path):
    view, label, _, build, mrays = line.split()
    if view not in views:
        views.append(view)
    runs[(view, label)].append((float(build), float(mrays)))
print(f"# First builds in a fresh process: A against B ({name})\n")
env = "".join(f'{k}="{v}" ' for k, v in (("ARGS_A", args_a), ("ARGS_B", args_b)) if v)
print(f"`{env}tests/bench/run_first_builds.sh A B {name}` with A = `{bin_a}`, B = `{bin_b}`: each run a "
      f"fresh rtc-bench process after {idle} s idle, {threads} threads, one build, then primary rays "
      "(median of 5). Build: the tree's build as rtc-bench times it (flattening plus kd-tree).\n")
print("| view | build ms A (runs) | build ms B (runs) | median A → B | B/A | primary M rays/s A → B |")
print("|---|---|---|---|---:|---|")
for view in views:
    a, b = runs[(view, "A")], runs[(view, "B")]
    ba, bb = statistics.median(x for x, _ in a), statistics.median(x for x, _ in b)
    ra, rb = statistics.median(y for _, y in a), statistics.median(y for _, y in b)
    print(f"| {view} | {', '.join(f'{x:.0f}' for x, _ in a)} | {', '.join(f'{x:.0f}' for x, _ in b)} | "
          f"{ba:.0f} → {bb:.0f} | {bb / ba:.2f} | {ra:.2f} → {rb:.2f} |")
EOF
echo "wrote $out/$name.txt and $out/$name.md" >&2
