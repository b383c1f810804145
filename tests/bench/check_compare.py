#!/usr/bin/env python3
"""ctest check of rtc-bench --compare-embree (label integration): runs it on the built-in scene
with 2 threads and asserts what must hold whatever the machine's speed:
  - one JSON line per mode (primary, shadow, full), each with rtc's figures and Embree's;
  - every ratio to Embree is there twice, of the medians and paired by repetition, positive and
    finite, and Embree's fastest mode is named and is one of the modes measured;
  - the build line has Embree's two builds and the paired build ratio;
  - the primary and shadow lines say each contender was timed after a pass of its own (warm_up);
  - rtc's rays agree with Embree's (hit/miss, occlusion) on all but a sliver of the pixels;
  - summarize.py turns the lines into a table with the scene's summary row.

usage: check_compare.py RTC_BENCH OUT_DIR
"""
import os
import shutil
import subprocess
import sys

from bench_checks import bench_json, check, failures, finite_positive


def positive(row, key):
    value = row.get(key)
    check(finite_positive(value), f"{row.get('mode')}: {key} = {value}")


def main(bench, out_dir):
    shutil.rmtree(out_dir, ignore_errors=True)
    os.makedirs(out_dir)
    stdout, rows = bench_json(bench, ["--threads", "2", "--reps", "3", "--compare-embree"])
    check(sorted(r["mode"] for r in rows) == ["full", "primary", "shadow"], f"modes {[r['mode'] for r in rows]}")
    for r in rows:
        for key in ("build_ms", "embree_build_ms", "embree_build_hq_ms", "build_vs_embree_hq_paired"):
            positive(r, key)
        if r["mode"] == "full":
            for key in ("frame_ms", "embree_frame_ms", "ratio_vs_embree_frame", "ratio_vs_embree_frame_paired"):
                positive(r, key)
            check(r.get("embree_frame_pixels_differing", 1.0) < 0.01,
                  f"full: {r.get('embree_frame_pixels_differing')} of the pixels differ from the Embree renderer's")
            continue
        check(r.get("warm_up") is True, f"{r['mode']}: warm_up = {r.get('warm_up')} (each contender's pass after one of its own)")
        for key in ("mrays_per_s", "mrays_per_s_single", "embree_best_mrays_per_s", "ratio_vs_embree_best",
                    "ratio_vs_embree_best_paired"):
            positive(r, key)
        embree = r.get("embree", {})
        check(r.get("embree_best_mode") in embree, f"{r['mode']}: fastest mode {r.get('embree_best_mode')} not in {list(embree)}")
        if r.get("embree_best_mode") in embree:
            best = embree[r["embree_best_mode"]]["mrays_per_s"]
            check(all(m["mrays_per_s"] <= best for m in embree.values()), f"{r['mode']}: a mode is faster than the 'fastest'")
            check(abs(r["embree_best_mrays_per_s"] - best) <= 1e-9 * best, f"{r['mode']}: best figure {best} mismatch")
        for name, m in embree.items():
            agree = m.get("hit_miss_agreement", m.get("occlusion_agreement"))
            check(agree is not None and agree > 0.999, f"{r['mode']} {name}: agreement {agree}")
    path = os.path.join(out_dir, "compare.jsonl")
    with open(path, "w") as f:
        f.write(stdout)
    summary = subprocess.run([sys.executable, os.path.join(os.path.dirname(__file__), "summarize.py"), path],
                             capture_output=True, text=True)
    check(summary.returncode == 0, f"summarize.py exit status {summary.returncode}: {summary.stderr[-2000:]}")
    scene = rows[0]["scene"] if rows else "?"
    check(f"| {scene} |" in summary.stdout, f"summarize.py's table has no row for {scene}")
    check("paired" in summary.stdout, "summarize.py's table does not say its ratios are paired")
    check("untimed pass of its own" in summary.stdout, "summarize.py's table does not say the contenders warm up")
    if failures:
        print(f"{len(failures)} check(s) failed")
        return 1
    print("rtc-bench --compare-embree: every figure and ratio present; summarize.py's table made")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2]))
