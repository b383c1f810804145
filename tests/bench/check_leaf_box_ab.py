#!/usr/bin/env python3
"""ctest check of rtc-bench --ab-kd-leaf-box-saving (label integration): on the built-in scene,
2 threads, 4 repetitions, a tree without leaf boxes against one with a box wherever a leaf's
triangles fill less than its cell, and asserts what must hold whatever the machine's speed:
  - exit status 0 and one JSON line per mode (primary, shadow);
  - the first tree has no boxes, the second has some, and the two gave the same answers;
  - both trees' throughputs and the paired ratios are positive and finite;
  - summarize_leaf_box_ab.py tabulates the lines.
Then the same for --ab-kd-empty-cut (every node swept against any empty gap cut at once),
--ab-kd-exact-below (the exact sweep below 4096 references against below 512, so more levels
binned), --ab-kd-footprint (the plain SAH against the view-aware one) and --ab-kd-mask-below (the
event sweep down to the leaves against bit masks below 128 references): the two trees' options
are recorded, the trees differ, they give the same answers, the figures (both trees' SAH costs
too) are finite and the summary tabulates them; --ab-kd-binned-root-above (the built-in scene as
one block against its root binned, with the exact sweep below 65,536: 1 block against 2, which
may be the same tree, the same answers); and --ab-kd-max-depth (the default depth limit
against 10), --ab-kd-traversal-cost (3 against 6), --ab-kd-intersection-cost (1 against 2) and
--ab-kd-empty-bonus (0.25 against 0), each a different tree with the same answers. Last,
--ab-shadow-order (far against dense: the same answers) and auto's tally in shadow mode (dense
and far timed, near not; "none" with no lights).

usage: check_leaf_box_ab.py RTC_BENCH
"""
import os
import subprocess
import sys
import tempfile

from bench_checks import bench_json, check, failures, finite_positive


def check_table(lines, count, column):
    """summarize_leaf_box_ab.py tabulates `lines`: a header with `column`, then one row per line."""
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "ab.txt")
        with open(path, "w") as f:
            f.write(lines)
        table = subprocess.run([sys.executable, os.path.join(os.path.dirname(__file__), "summarize_leaf_box_ab.py"),
                                path, "check"], capture_output=True, text=True, timeout=60)
        check(table.returncode == 0, f"summarize_leaf_box_ab.py exit status {table.returncode}: {table.stderr}")
        rows_out = [l for l in table.stdout.splitlines() if l.startswith("| ")]
        check(len(rows_out) == 1 + count, "summarize_leaf_box_ab.py: not a header and one row per line")
        check(bool(rows_out) and column in rows_out[0], f"summarize_leaf_box_ab.py: no column {column!r}")


def run_ab(bench, reps, options, column, check_row):
    """rtc-bench's primary and shadow modes with `options` (a first tree and an --ab-kd-* second):
    exit 0, one JSON line per mode, the same answers from both trees, finite figures, `check_row`
    on each line, and a summary table with `column`."""
    stdout, rows = bench_json(bench, ["--threads", "2", "--reps", str(reps), "--build-reps", "1", "--mode", "primary",
                                      "--mode", "shadow", *options])
    check([r.get("mode") for r in rows] == ["primary", "shadow"], f"modes {[r.get('mode') for r in rows]}")
    for r in rows:
        ab = r.get("ab", {})
        mode = r.get("mode")
        check_row(r, ab, mode)
        check(ab.get("answers_differ") == 0, f"{mode}: {ab.get('answers_differ')} answers differ between the trees")
        for key in ("mrays_per_s", "mrays_per_s_single", "speed_vs_first_paired", "speed_vs_first_single_paired"):
            check(finite_positive(ab.get(key)), f"{mode}: ab.{key} = {ab.get(key)}")
        check(finite_positive(r.get("mrays_per_s")), f"{mode}: mrays_per_s = {r.get('mrays_per_s')}")
    if rows:
        check_table(stdout, len(rows), column)


def leaf_boxes(r, ab, mode):
    check(r.get("kd_leaf_boxes") == 0, f"{mode}: the first tree has {r.get('kd_leaf_boxes')} leaf boxes, expected 0")
    check(isinstance(ab.get("kd_leaf_boxes"), int) and ab["kd_leaf_boxes"] > 0,
          f"{mode}: the second tree has {ab.get('kd_leaf_boxes')} leaf boxes, expected some")


def other_tree(key, first, second):
    """A check_row for an option `key` given as `first` and `second`: recorded, and the trees
    differ (node counts) with finite SAH costs."""
    def check_row(r, ab, mode):
        check(r.get(key) == first and ab.get(key) == second,
              f"{mode}: {key} {r.get(key)} and {ab.get(key)}, expected {first} and {second}")
        check(isinstance(ab.get("kd_nodes"), int) and ab["kd_nodes"] > 0, f"{mode}: ab.kd_nodes = {ab.get('kd_nodes')}")
        check(ab.get("kd_nodes") != r.get("kd_nodes"), f"{mode}: both trees have {r.get('kd_nodes')} nodes")
        check(finite_positive(r.get("kd_sah_cost")) and finite_positive(ab.get("kd_sah_cost")),
              f"{mode}: SAH costs {r.get('kd_sah_cost')} and {ab.get('kd_sah_cost')}")
    return check_row


def main(bench):
    run_ab(bench, 4, ["--kd-leaf-box-saving", "0", "--ab-kd-leaf-box-saving", "0.000001"], "boxes (1e-06)", leaf_boxes)
    # The built-in scene has gaps the sweep does not cut first (40,553 nodes against 39,759).
    run_ab(bench, 3, ["--kd-empty-cut", "2", "--ab-kd-empty-cut", "0"], "nodes (2 → 0)",
           other_tree("kd_empty_cut", 2, 0))
    # The built-in scene (38,072 triangles) has nodes of 512 to 4096 references, which the two
    # thresholds split differently (40,559 nodes against 41,939).
    run_ab(bench, 3, ["--kd-exact-below", "4096", "--ab-kd-exact-below", "512"], "nodes (4096 → 512)",
           other_tree("kd_exact_below", 4096, 512))
    # With the exact sweep below 65,536 the built-in scene is one block unless its root is binned
    # (--kd-binned-root-above 1024): one block against two, the options recorded.
    def binned_root(r, ab, mode):
        check(r.get("kd_binned_root_above") == 65536 and ab.get("kd_binned_root_above") == 1024,
              f"{mode}: kd_binned_root_above {r.get('kd_binned_root_above')} and {ab.get('kd_binned_root_above')}")
        check(r.get("kd_blocks") == 1 and ab.get("kd_blocks") == 2,
              f"{mode}: {r.get('kd_blocks')} and {ab.get('kd_blocks')} blocks, expected 1 and 2")
        check(finite_positive(r.get("kd_sah_cost")) and finite_positive(ab.get("kd_sah_cost")),
              f"{mode}: SAH costs {r.get('kd_sah_cost')} and {ab.get('kd_sah_cost')}")
    run_ab(bench, 3, ["--kd-exact-below", "65536", "--kd-binned-root-above", "65536", "--ab-kd-binned-root-above",
                      "1024"], "nodes (65536 → 1024)", binned_root)
    run_ab(bench, 3, ["--kd-footprint", "0", "--ab-kd-footprint", "2"], "nodes (0 → 2)",
           other_tree("kd_footprint", 0, 2))
    run_ab(bench, 3, ["--kd-mask-below", "0", "--ab-kd-mask-below", "128"], "nodes (0 → 128)",
           other_tree("kd_mask_below", 0, 128))
    # A depth limit of 10 (0: the default rule, 8 + 1.3 log2 N = 27 here) gives a shallower tree.
    def depth_limit(r, ab, mode):
        other_tree("kd_max_depth_limit", 0, 10)(r, ab, mode)
        check(isinstance(ab.get("kd_max_depth"), int) and ab["kd_max_depth"] <= 10,
              f"{mode}: the second tree reaches depth {ab.get('kd_max_depth')}, limit 10")
    run_ab(bench, 3, ["--kd-max-depth", "0", "--ab-kd-max-depth", "10"], "nodes (0 → 10)", depth_limit)
    # The SAH's constants (values exact in float, so the JSON gives them back as given): a larger
    # K_T or K_I, or no empty-space bonus, gives another tree on the built-in scene (28,171 nodes
    # against 14,723, 52,197 and 18,285).
    run_ab(bench, 3, ["--kd-traversal-cost", "3", "--ab-kd-traversal-cost", "6"], "nodes (3 → 6)",
           other_tree("kd_traversal_cost", 3, 6))
    run_ab(bench, 3, ["--kd-intersection-cost", "1", "--ab-kd-intersection-cost", "2"], "nodes (1 → 2)",
           other_tree("kd_intersection_cost", 1, 2))
    run_ab(bench, 3, ["--kd-empty-bonus", "0.25", "--ab-kd-empty-bonus", "0"], "nodes (0.25 → 0)",
           other_tree("kd_empty_bonus", 0.25, 0))
    check_shadow_orders(bench)
    print(f"{len(failures)} failure(s)")
    return 1 if failures else 0


def check_shadow_orders(bench):
    """--ab-shadow-order: the far order against the dense one, the same answers, finite figures,
    and auto's tally recorded (shadow_walks); with no lights (no shadow rays) auto never settles
    and says so ("none") instead of failing."""
    _, rows = bench_json(bench, ["--threads", "2", "--reps", "3", "--build-reps", "1", "--mode", "shadow",
                                 "--shadow-order", "far", "--ab-shadow-order", "dense"])
    check(len(rows) == 1, f"--ab-shadow-order: {len(rows)} JSON lines, expected 1")
    for r in rows:
        ab = r.get("ab_shadow_order", {})
        check(ab.get("order") == "dense", f"ab_shadow_order.order = {ab.get('order')}")
        check(ab.get("answers_differ") == 0, f"{ab.get('answers_differ')} answers differ between far and dense")
        for key in ("mrays_per_s", "speed_vs_first_paired"):
            check(finite_positive(ab.get(key)), f"ab_shadow_order.{key} = {ab.get(key)}")
    _, rows = bench_json(bench, ["--threads", "2", "--reps", "2", "--build-reps", "1", "--mode", "shadow"])
    for r in rows:
        walks = r.get("shadow_walks", {})
        check(walks.get("preferred") in ("dense", "far"), f"auto settled on {walks.get('preferred')}")
        check(walks.get("near", {}).get("timed_rays") == 0, "auto timed near-first walks")
        for order in ("dense", "far"):
            check(walks.get(order, {}).get("timed_rays", 0) > 0, f"auto timed no {order} walks")
    _, rows = bench_json(bench, ["--threads", "2", "--reps", "1", "--build-reps", "1", "--mode", "shadow", "--no-lights"])
    for r in rows:
        check(r.get("shadow_walks", {}).get("preferred") == "none",
              f"no lights: auto settled on {r.get('shadow_walks', {}).get('preferred')}")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    sys.exit(main(sys.argv[1]))
