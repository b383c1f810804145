#!/usr/bin/env python3
"""ctest check of rtc-bench --kernel-ab (label integration): runs it on the built-in scene with
2 threads and an even number of repetitions (4) and asserts what must hold whatever the
machine's speed:
  - exit status 0 and one JSON line for the full frame;
  - the four kernels (general and specialised, each without and with empty-space skipping) gave
    the same pixels;
  - every repetition's time is there (4 per kernel), positive and finite;
  - each kernel's median is the mean of its middle two times, its fastest the least of them;
  - each kernel's paired ratio is the median (mean of the middle two) of its time over the
    general kernel's repetition by repetition, and the general kernel's ratio to itself is 1;
  - the reported share of primary rays skipped is a fraction.

usage: check_kernel_ab.py RTC_BENCH
"""
import math
import statistics
import sys

from bench_checks import bench_json, check, failures, finite_positive

KERNELS = ("general", "specialised", "general_skip", "specialised_skip")


def main(bench):
    _, rows = bench_json(bench, ["--threads", "2", "--reps", "1", "--mode", "full", "--kernel-ab", "--ab-reps", "4"])
    check(len(rows) == 1, f"{len(rows)} JSON lines, expected 1")
    if not rows:
        return
    row = rows[0]
    check(row.get("mode") == "full", f"mode {row.get('mode')}")
    check(row.get("kernel_ab_reps") == 4, f"kernel_ab_reps {row.get('kernel_ab_reps')}")
    check(row.get("kernel_ab_same_pixels") is True, "the four kernels gave different pixels")
    ms, fastest, ratio = row.get("kernel_ab_ms", {}), row.get("kernel_ab_min_ms", {}), row.get("kernel_ab_ratio", {})
    reps = row.get("kernel_ab_rep_ms", {})
    for k in KERNELS:
        times = reps.get(k)
        check(isinstance(times, list) and len(times) == 4 and all(finite_positive(t) for t in times),
              f"kernel_ab_rep_ms[{k}] = {times}")
    if failures:
        return
    for k in KERNELS:
        check(math.isclose(ms.get(k, -1), statistics.median(reps[k]), rel_tol=1e-12),
              f"{k}: median {ms.get(k)} of {reps[k]}")
        check(fastest.get(k) == min(reps[k]), f"{k}: fastest {fastest.get(k)} of {reps[k]}")
        paired = statistics.median([a / b for a, b in zip(reps[k], reps["general"])])
        check(math.isclose(ratio.get(k, -1), paired, rel_tol=1e-12),
              f"{k}: paired ratio {ratio.get(k)}, expected {paired}")
    check(ratio.get("general") == 1.0, f"the general kernel's ratio to itself is {ratio.get('general')}")
    skipped = row.get("primary_skipped_fraction")
    check(isinstance(skipped, (int, float)) and 0.0 <= skipped <= 1.0, f"primary_skipped_fraction {skipped}")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    main(sys.argv[1])
    if failures:
        print(f"{len(failures)} check(s) failed", file=sys.stderr)
        sys.exit(1)
    print("rtc-bench --kernel-ab: all checks passed")
