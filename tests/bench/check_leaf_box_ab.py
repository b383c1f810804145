#!/usr/bin/env python3
"""ctest check of rtc-bench --ab-kd-leaf-box-saving (label integration): on the built-in scene,
2 threads, 4 repetitions, a tree without leaf boxes against one with a box wherever a leaf's
triangles fill less than its cell, and asserts what must hold whatever the machine's speed:
  - exit status 0 and one JSON line per mode (primary, shadow);
  - the first tree has no boxes, the second has some, and the two gave the same answers;
  - both trees' throughputs and the paired ratios are positive and finite;
  - summarize_leaf_box_ab.py tabulates the lines.
Then the same for --ab-kd-empty-cut (every node swept against any empty gap cut at once): the
two trees' options are recorded, they give the same answers, and the figures are finite.

usage: check_leaf_box_ab.py RTC_BENCH
"""
import json
import os
import subprocess
import sys
import tempfile

from bench_checks import check, failures, finite_positive


def main(bench):
    run = subprocess.run([bench, "--threads", "2", "--reps", "4", "--build-reps", "1", "--mode", "primary", "--mode",
                          "shadow", "--kd-leaf-box-saving", "0", "--ab-kd-leaf-box-saving", "0.000001", "--json"],
                         capture_output=True, text=True, timeout=240)
    check(run.returncode == 0, f"rtc-bench exit status {run.returncode}: {run.stderr[-2000:]}")
    rows = [json.loads(line) for line in run.stdout.splitlines() if line.startswith("{")]
    check([r.get("mode") for r in rows] == ["primary", "shadow"], f"modes {[r.get('mode') for r in rows]}")
    for r in rows:
        ab = r.get("ab", {})
        mode = r.get("mode")
        check(r.get("kd_leaf_boxes") == 0, f"{mode}: the first tree has {r.get('kd_leaf_boxes')} leaf boxes, expected 0")
        check(isinstance(ab.get("kd_leaf_boxes"), int) and ab["kd_leaf_boxes"] > 0,
              f"{mode}: the second tree has {ab.get('kd_leaf_boxes')} leaf boxes, expected some")
        check(ab.get("answers_differ") == 0, f"{mode}: {ab.get('answers_differ')} answers differ between the trees")
        for key in ("mrays_per_s", "mrays_per_s_single", "speed_vs_first_paired", "speed_vs_first_single_paired"):
            check(finite_positive(ab.get(key)), f"{mode}: ab.{key} = {ab.get(key)}")
        check(finite_positive(r.get("mrays_per_s")), f"{mode}: mrays_per_s = {r.get('mrays_per_s')}")
    if rows:
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "ab.txt")
            with open(path, "w") as f:
                f.write(run.stdout)
            table = subprocess.run([sys.executable, os.path.join(os.path.dirname(__file__), "summarize_leaf_box_ab.py"),
                                    path, "check"], capture_output=True, text=True, timeout=60)
            check(table.returncode == 0, f"summarize_leaf_box_ab.py exit status {table.returncode}: {table.stderr}")
            rows_out = [l for l in table.stdout.splitlines() if l.startswith("| ")]
            check(len(rows_out) == 1 + len(rows), "summarize_leaf_box_ab.py: not a header and one row per line")
    cut = subprocess.run([bench, "--threads", "2", "--reps", "3", "--build-reps", "1", "--mode", "primary", "--mode",
                          "shadow", "--kd-empty-cut", "2", "--ab-kd-empty-cut", "0", "--json"],
                         capture_output=True, text=True, timeout=240)
    check(cut.returncode == 0, f"rtc-bench --ab-kd-empty-cut exit status {cut.returncode}: {cut.stderr[-2000:]}")
    cut_rows = [json.loads(line) for line in cut.stdout.splitlines() if line.startswith("{")]
    check([r.get("mode") for r in cut_rows] == ["primary", "shadow"], f"modes {[r.get('mode') for r in cut_rows]}")
    for r in cut_rows:
        ab = r.get("ab", {})
        mode = r.get("mode")
        check(r.get("kd_empty_cut") == 2 and ab.get("kd_empty_cut") == 0,
              f"{mode}: empty cuts {r.get('kd_empty_cut')} and {ab.get('kd_empty_cut')}, expected 2 and 0")
        check(isinstance(ab.get("kd_nodes"), int) and ab["kd_nodes"] > 0, f"{mode}: ab.kd_nodes = {ab.get('kd_nodes')}")
        check(ab.get("answers_differ") == 0, f"{mode}: {ab.get('answers_differ')} answers differ between the trees")
        for key in ("mrays_per_s", "speed_vs_first_paired", "speed_vs_first_single_paired"):
            check(finite_positive(ab.get(key)), f"{mode}: ab.{key} = {ab.get(key)}")
    print(f"{len(failures)} failure(s)")
    return 1 if failures else 0


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    sys.exit(main(sys.argv[1]))
