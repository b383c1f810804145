#!/usr/bin/env python3
"""Tabulates run_leaf_box_ab.sh: per view and mode, both trees' throughput and the second
tree's speed over the first's, paired rep by rep within one process (rtc-bench
--ab-kd-leaf-box-saving, --ab-kd-empty-cut, --ab-kd-exact-below, --ab-kd-binned-root-above,
--ab-kd-footprint, --ab-kd-mask-below, --ab-kd-max-depth, --ab-kd-traversal-cost,
--ab-kd-intersection-cost or --ab-kd-empty-bonus, whichever the two trees differ in), with the
medians over the views.
Usage: summarize_leaf_box_ab.py RESULTS.txt "COMMAND"."""
import json
import statistics
import sys


def main() -> None:
    rows = [json.loads(line) for line in open(sys.argv[1]) if line.strip()]
    if not rows:
        sys.exit(f"{sys.argv[1]}: no results")
    first = rows[0]
    # Older lines (before --ab-kd-empty-cut, --ab-kd-exact-below) carry neither key: leaf boxes.
    def differs(k):
        return k in first and first.get(k) != first["ab"].get(k, first.get(k))

    # The option the trees differ in, by the first key of this list that differs, and whether its
    # rows show both trees' SAH costs; no key differing means leaf boxes.
    options = [("kd_footprint", "View-aware SAH (packet footprint, pixels)", True),
               ("kd_mask_below", "Bit masks (not clipped) below", True),
               ("kd_exact_below", "Exact sweep below", True),
               ("kd_binned_root_above", "Root binned above", True),
               ("kd_max_depth_limit", "Depth limit (0: 8 + 1.3 log2 N)", True),
               ("kd_traversal_cost", "SAH traversal cost K_T", True),
               ("kd_intersection_cost", "SAH intersection cost K_I", True),
               ("kd_empty_bonus", "SAH empty-space bonus", True),
               ("kd_empty_cut", "Empty gaps cut without the sweep", False)]
    key, title, show_sah = next((o for o in options if differs(o[0])), ("kd_leaf_box_saving", "Leaf boxes", False))
    cut = key != "kd_leaf_box_saving"  # trees of different shapes: their node counts
    size, size_label = ("kd_nodes", "nodes") if cut else ("kd_leaf_boxes", "boxes")
    a, b = first[key], first["ab"][key]
    option = "kd_max_depth" if key == "kd_max_depth_limit" else key
    print(f"# {title}: --{option.replace('_', '-')} {b:g} against {a:g}\n")
    print(f"Regenerate with `{sys.argv[2]}`. {first['threads']} thread(s), isa {first['isa']}, "
          f"{first['reps']} reps, process CPU time. Each view is one process: both trees are built, then "
          "their packets and single rays take turns rep by rep; a ratio is the median over the reps of "
          "the first tree's time over the second's (above 1: the second is faster). `differ`: rays whose "
          "answers differ between the trees (must be 0).\n")
    sizes_head = f"{size_label} ({a:g} → {b:g})" if cut else f"{size_label} ({b:g})"
    print(f"| scene | tris | mode | {sizes_head} | packets {a:g} | packets {b:g} | ratio | single {a:g} | "
          f"single {b:g} | ratio | differ |")
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    ratios = {"primary": ([], []), "shadow": ([], [])}
    for r in rows:
        ab = r["ab"]
        ratios[r["mode"]][0].append(ab["speed_vs_first_paired"])
        ratios[r["mode"]][1].append(ab["speed_vs_first_single_paired"])
        sizes = f"{r[size]:,} → {ab[size]:,}" if cut else f"{ab[size]:,}"
        if show_sah and "kd_sah_cost" in ab:
            sizes += f" (SAH {r['kd_sah_cost']:.2f} → {ab['kd_sah_cost']:.2f})"
        print(f"| {r['scene']} | {r['triangles']:,} | {r['mode']} | {sizes} | "
              f"{r['mrays_per_s']:.2f} | {ab['mrays_per_s']:.2f} | **{ab['speed_vs_first_paired']:.3f}** | "
              f"{r['mrays_per_s_single']:.2f} | {ab['mrays_per_s_single']:.2f} | "
              f"{ab['speed_vs_first_single_paired']:.3f} | {ab['answers_differ']} |")
    print()
    for mode, (p, s) in ratios.items():
        if p:
            print(f"- {mode}: packets median {statistics.median(p):.3f} (views {min(p):.3f}-{max(p):.3f}), "
                  f"single rays median {statistics.median(s):.3f} ({min(s):.3f}-{max(s):.3f})")


if __name__ == "__main__":
    main()
