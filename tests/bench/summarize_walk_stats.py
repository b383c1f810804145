#!/usr/bin/env python3
"""Markdown tables from run_walk_stats.sh's JSON lines (rtc-bench of the stats preset)."""
import json
import sys


def per(n, d):
    return n / d if d else 0.0


def cells(w):
    """Per walk: lanes, inner steps, leaves with triangles (+ empty), pushes, tests, lanes per test."""
    n = w["walks"]
    return [f"{per(w['lanes'], n):.2f}", f"{per(w['inner'], n):.1f}",
            f"{per(w['leaves'], n):.2f} (+{per(w['empty_leaves'], n):.2f})", f"{per(w['pushes'], n):.1f}",
            f"{per(w['tests'], n):.1f}", f"{per(w['test_lanes'], w['tests']):.2f}"]


def main(path):
    rows = [json.loads(line) for line in open(path) if line.startswith("{")]
    if not rows:
        sys.exit(f"summarize_walk_stats: no results in {path}")
    if "walks_packets" not in rows[0]:
        sys.exit(f"summarize_walk_stats: {path} has no walk counts (rtc-bench not built with RTC_WALK_STATS)")
    isa = rows[0].get("isa", "?")
    print("# What the kd-tree walks do on the shared scenes\n")
    print("Regenerate with `tests/bench/run_walk_stats.sh` (the `stats` preset, `RTC_WALK_STATS`: rtc-bench with "
          "walk counts; one thread, one pass per mode). Per walk of a packet (one "
          f"`traverse_coherent` call: a packet of the {isa} kernel or a same-octant group of its lanes) and per "
          "single ray: live lanes at the start, inner-node steps, leaves with triangles entered (+ empty leaves "
          "entered; packets pass marked empty children by), subtrees pushed, triangle tests (a leaf tested side "
          "by side for one lane counts each of its triangles) and the lanes live in a test. 'lone' is the share "
          "of a packet pass's rays walked alone (octant groups of one lane). 'leaf boxes': the packets' leaf box "
          "tests per walk (KdBuildOptions::leaf_box_saving), in brackets those that let no lane through. Shadow rays are walked from "
          "their origin (`--shadow-order near`) and from the light's end (`far`), each order fixed, so "
          "every count is the same in every run (`auto` picks per run of packets by timings).\n")
    tables = (("primary", None, "primary rays"), ("shadow", "near", "shadow rays from the origin (near)"),
              ("shadow", "far", "shadow rays from the light's end (far)"))
    for mode, order, title in tables:
        print(f"## {title}\n")
        print("| scene | tris | rays | packet lanes | inner | leaves | pushes | tests | lanes/test | leaf boxes | lone | "
              "single inner | single leaves | single tests | inner: packet / lanes x single |")
        print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        for r in rows:
            if r.get("mode") != mode or (order is not None and r.get("shadow_order") != order):
                continue
            p, lone, s = r["walks_packets"], r["walks_packet_lone_lanes"], r["walks_single"]
            c = cells(p)
            sc = cells(s)
            lanes_total = p["lanes"] + lone["lanes"]
            # The packet's inner steps against what its lanes would take one by one.
            ratio = per(per(p["inner"], p["walks"]), per(p["lanes"], p["walks"]) * per(s["inner"], s["walks"]))
            boxes = (f"{per(p.get('box_tests', 0), p['walks']):.2f} "
                     f"({per(p.get('box_skips', 0), p['walks']):.2f})")
            print(f"| {r['scene']} | {r['triangles']:,} | {r['rays']:,} | {c[0]} | {c[1]} | {c[2]} | {c[3]} | {c[4]} | "
                  f"{c[5]} | {boxes} | {100.0 * per(lone['lanes'], lanes_total):.1f}% | {sc[1]} | {sc[2]} | {sc[4]} | "
                  f"{ratio:.2f} |")
        print()


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "tests/bench/results/walk_stats.jsonl")
