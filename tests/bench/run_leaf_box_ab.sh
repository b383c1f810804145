#!/usr/bin/env bash
# Leaf boxes (KdBuildOptions::leaf_box_saving), or with AB_OPTION=kd-empty-cut the empty-gap cut
# (KdBuildOptions::empty_cut), with AB_OPTION=kd-exact-below the size of the exact sweep's blocks
# (KdBuildOptions::exact_below), with AB_OPTION=kd-binned-root-above the size above which the root
# is binned (KdBuildOptions::binned_root_above), with AB_OPTION=kd-footprint the pixels the view-aware SAH adds
# to a small node's lengths (KdBuildOptions::footprint_pixels), with AB_OPTION=kd-mask-below
# the size of the subtrees built with bit masks (KdBuildOptions::mask_below), or with
# AB_OPTION=kd-max-depth the depth limit (KdBuildOptions::max_depth), or with
# AB_OPTION=kd-traversal-cost, kd-intersection-cost or kd-empty-bonus the SAH's K_T, K_I or
# empty-space bonus (KdBuildOptions::traversal_cost, intersection_cost, empty_bonus), at two values on
# every view of the shared scene pack, in one process per view: rtc-bench builds a tree with
# each value and times both trees' packets and single rays rep by rep (--ab-kd-leaf-box-saving /
# --ab-kd-empty-cut / --ab-kd-exact-below / --ab-kd-binned-root-above / --ab-kd-footprint / --ab-kd-mask-below /
# --ab-kd-max-depth / --ab-kd-traversal-cost / --ab-kd-intersection-cost / --ab-kd-empty-bonus), so a slow
# spell of the machine falls on both alike, and checks that both trees give the same answers.
# Writes tests/bench/results/NAME.txt (rtc-bench's JSON lines) and NAME.md
# (tests/bench/summarize_leaf_box_ab.py: per view and mode, the second value's speed over the
# first's, paired rep by rep).
# Usage: tests/bench/run_leaf_box_ab.sh NAME [SCENES_DIR] [THREADS] [REPS] [A] [B]
#   defaults: ../shared/scenes, 1 thread, 15 reps, A = 0 (no boxes), B = 2 (the default); with
#   AB_OPTION=kd-empty-cut, kd-exact-below, kd-binned-root-above, kd-footprint, kd-mask-below,
#   kd-max-depth, kd-traversal-cost, kd-intersection-cost or kd-empty-bonus A and B are required
#   (e.g. 2 0.2: off against the default; 4096 1024; 4096 1024; 0 2; 64 128; 0 40; 3 2.5; 1 1.5;
#   0.2 0.1)
# RTC_BENCH: the rtc-bench binary (default build/release/tests/bench/rtc-bench); AB_ISA: the
# kernel ISA (default: rtc-bench's, the widest the CPU runs).
set -euo pipefail
cd "$(dirname "$0")/../.."
[ $# -ge 1 ] || { echo "usage: $0 NAME [SCENES_DIR] [THREADS] [REPS] [A] [B]" >&2; exit 2; }
name=$1
scenes=${2:-../shared/scenes}
threads=${3:-1}
reps=${4:-15}
option=${AB_OPTION:-kd-leaf-box-saving}
case "$option" in
  kd-leaf-box-saving) a=${5:-0} b=${6:-2} ;;
  kd-empty-cut | kd-exact-below | kd-binned-root-above | kd-footprint | kd-mask-below | kd-max-depth | \
    kd-traversal-cost | kd-intersection-cost | kd-empty-bonus)
    [ $# -ge 6 ] || { echo "run_leaf_box_ab: AB_OPTION=$option needs A and B" >&2; exit 2; }
    a=$5 b=$6 ;;
  *) echo "run_leaf_box_ab: AB_OPTION must be kd-leaf-box-saving, kd-empty-cut, kd-exact-below," \
      "kd-binned-root-above, kd-footprint, kd-mask-below, kd-max-depth, kd-traversal-cost," \
      "kd-intersection-cost or kd-empty-bonus, got $option" >&2
    exit 2 ;;
esac
bench=${RTC_BENCH:-build/release/tests/bench/rtc-bench}
[ -d "$scenes" ] || { echo "run_leaf_box_ab: $scenes is not a folder (the shared scene pack)" >&2; exit 1; }
if [ -n "${RTC_BENCH:-}" ]; then
  [ -x "$bench" ] || { echo "run_leaf_box_ab: RTC_BENCH=$bench is not an executable" >&2; exit 1; }
elif [ ! -x "$bench" ]; then
  cmake --preset release >/dev/null && cmake --build --preset release --target rtc-bench
fi
isa_args=${AB_ISA:+--isa $AB_ISA}
out=tests/bench/results
mkdir -p "$out"
: > "$out/$name.txt.tmp"
views=$(find -L "$scenes" -name 'view*.json' | sort)
[ -n "$views" ] || { echo "run_leaf_box_ab: no view*.json under $scenes" >&2; exit 1; }
for view in $views; do
  echo "$bench $view --$option $a --ab-$option $b ($threads threads, $reps reps)" >&2
  # shellcheck disable=SC2086  # isa_args is words
  "$bench" "$view" --threads "$threads" --reps "$reps" --build-reps 1 --mode primary --mode shadow $isa_args \
    --cpu-time --json "--$option" "$a" "--ab-$option" "$b" >> "$out/$name.txt.tmp"
done
mv "$out/$name.txt.tmp" "$out/$name.txt"
python3 tests/bench/summarize_leaf_box_ab.py "$out/$name.txt" \
  "${AB_OPTION:+AB_OPTION=$option }tests/bench/run_leaf_box_ab.sh $name $scenes $threads $reps $a $b" > "$out/$name.md"
echo "wrote $out/$name.txt and $out/$name.md" >&2
