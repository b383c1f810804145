#!/usr/bin/env python3
"""A markdown table from run_tile_shares.sh's JSON lines: per view and share of the image's tiles,
rtc's footprint (stats build) and primary rays against Embree's best mode at 1 and 2 threads."""
import json
import sys


def main(path):
    rows = [json.loads(line) for line in open(path) if line.startswith("{")]
    rows = [r for r in rows if r.get("mode") == "primary"]
    if not rows:
        sys.exit(f"summarize_tile_shares: no primary-mode results in {path}")
    if any("tiles" not in r for r in rows):
        sys.exit(f"summarize_tile_shares: {path} has runs without the tile share (an rtc-bench before --tiles)")
    timed, footprint = {}, {}
    order = []
    for r in rows:
        key = (r["scene"], tuple(r["tiles"]))
        if key not in order:
            order.append(key)
        if "footprint_packets" in r:
            if key in footprint:
                sys.exit(f"summarize_tile_shares: two footprints of {key[0]} tiles {key[1]} in {path}")
            footprint[key] = r["footprint_packets"]
        elif "ratio_vs_embree_best_paired" in r:
            if r.get("threads") not in (1, 2):
                sys.exit(f"summarize_tile_shares: a run of {key[0]} with {r.get('threads')} threads (the table has "
                         "columns for 1 and 2)")
            if (key, r["threads"]) in timed:
                sys.exit(f"summarize_tile_shares: two runs of {key[0]} tiles {key[1]} at {r['threads']} threads in "
                         f"{path}")
            timed[(key, r["threads"])] = r
        else:
            sys.exit(f"summarize_tile_shares: a run of {key[0]} has neither a footprint (stats build) nor Embree's "
                     "figures (--compare-embree)")
    cpu = rows[0].get("cpu", "?")
    widths = {t["isas"][t["isa"]]["packet_width"] for t in timed.values() if t.get("isa") in t.get("isas", {})}
    width = f"{widths.pop()}-wide" if len(widths) == 1 else "best ISA's"
    print("# rtc's primary rays against Embree on parts of the image\n")
    print("Regenerate with `tests/bench/run_tile_shares.sh` (rtc-bench `--mode primary --compare-embree --tiles "
          f"FROM:TO`, the best ISA, {cpu}). A part is a share of the image's 16x16 tiles in rows from the top, traced "
          "by every side alike. Footprint: the distinct 64-byte lines of rtc's kd nodes and leaf slots (triangle "
          "records and leaf boxes) that one pass of its packets reads or asks for ahead (the stats preset), the "
          f"working set a core's caches would have to hold. Ratio: rtc's {width} packets over Embree's best mode "
          "(M rays/s), the median of the ratios paired by round; above 1, rtc is faster.\n")
    print("| view | tiles | rays | rtc footprint MB: nodes | leaf slots | 1 thread: rtc M rays/s | Embree best | "
          "ratio | 2 threads: rtc | Embree best | ratio |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for key in order:
        scene, tiles = key
        f = footprint.get(key)
        cells = [scene, f"{tiles[0]:g}-{tiles[1]:g}"]
        run = timed.get((key, 1)) or timed.get((key, 2))
        cells.append(f"{run['rays']:,}" if run else "-")
        cells += [f"{f['node_lines'] * 64 / 1e6:.2f}", f"{f['record_lines'] * 64 / 1e6:.2f}"] if f else ["-", "-"]
        for threads in (1, 2):
            t = timed.get((key, threads))
            if t is None:
                cells += ["-", "-", "-"]
                continue
            cells += [f"{t['mrays_per_s']:.2f}", f"{t['embree_best_mrays_per_s']:.2f} ({t['embree_best_mode']})",
                      f"{t['ratio_vs_embree_best_paired']:.2f}"]
        print("| " + " | ".join(cells) + " |")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: summarize_tile_shares.py RESULTS.jsonl")
    main(sys.argv[1])
