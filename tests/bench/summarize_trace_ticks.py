#!/usr/bin/env python3
"""Markdown tables from run_trace_ticks.sh's JSON lines (rtc-bench of the ticks preset, full mode)."""
import json
import sys


def side(row, name):
    return row.get(name, {"ticks_per_frame": 0.0, "calls_per_frame": 0.0, "rays_per_frame": 0.0})


def ratio(a, b):
    return f"{a / b:.3f}" if a > 0 and b > 0 else "-"


def main(path):
    views = [json.loads(line) for line in open(path) if line.startswith("{")]
    views = [v for v in views if v.get("mode") == "full"]
    if not views:
        sys.exit(f"summarize_trace_ticks: no full-mode results in {path}")
    if any("trace_ticks" not in v for v in views):
        sys.exit(f"summarize_trace_ticks: {path} has no trace-call tally (rtc-bench not built with RTC_TRACE_TICKS)")
    if any("embree_frame_ms" not in v for v in views):
        sys.exit(f"summarize_trace_ticks: {path} lacks the Embree renderer (run with --compare-embree)")
    if any("trace_ticks_tsc_ghz" not in v for v in views):
        sys.exit(f"summarize_trace_ticks: {path} lacks the counter's rate (trace_ticks_tsc_ghz: an older rtc-bench)")
    if any(v.get("threads") != 1 for v in views):
        sys.exit(f"summarize_trace_ticks: {path} has runs with more than one thread (ticks add up over threads, "
                 "frame times do not; run with --threads 1)")
    cpu = views[0].get("cpu", "?")
    print("# Where the frames' tracing time goes: rtc against the Embree renderer\n")
    print("Regenerate with `tests/bench/run_trace_ticks.sh` (the `ticks` preset, `RTC_TRACE_TICKS`: rtc-bench whose "
          "renderer reads the time stamp counter around its two trace calls, closest hits and occlusion, on rtc's "
          f"kd-trees and on the Embree renderer's tracer alike; one thread; {cpu}). Per frame (the mean over the "
          "frames each side rendered), by kind of call and by how many of the packet's lanes carry a ray: each "
          "side's ticks (M) and ticks per call, rays per call (the same rays on both sides), and the Embree "
          "renderer's ticks over rtc's (above 1: "
          "rtc spends less there). 'Rest of the frame': the frame's median time at the counter's rate less its "
          "trace calls' mean (shading, ray set-up, tiles), the same code on both sides; median against mean, "
          "so a few M ticks either way are noise. Frame ratio: the Embree "
          "renderer's time over rtc's (above 1: rtc faster). 'rtc less Embree': rtc's ticks less the Embree "
          "renderer's per class of call, summed over the lights (negative: rtc spends less). The clock reads cost about 100 ticks a call on both "
          "sides.\n")
    print("## Summary\n")
    print("| view | frame rtc ms | Embree renderer ms | frame ratio | trace calls rtc M ticks | Embree M ticks | "
          "ratio | rest rtc M ticks | rest Embree | rtc less Embree (M ticks): primary | mirror | "
          "shadow, all lanes | shadow, more than half | shadow, at most half |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    # Calls (TraceCall) 0 primary, 1 mirror, 2 shadow; fills (LaneFill) 0 all, 1 more than half, 2 at most half.
    classes = ((0, None), (1, None), (2, 0), (2, 1), (2, 2))
    for v in views:
        rows = v["trace_ticks"]
        ghz = v["trace_ticks_tsc_ghz"]
        r = sum(side(x, "rtc")["ticks_per_frame"] for x in rows)
        e = sum(side(x, "embree")["ticks_per_frame"] for x in rows)
        rest_r = v["frame_ms"] * ghz * 1e6 - r
        rest_e = v["embree_frame_ms"] * ghz * 1e6 - e
        excess = []
        for call, fill in classes:
            d = sum(side(x, "rtc")["ticks_per_frame"] - side(x, "embree")["ticks_per_frame"] for x in rows
                    if x["call"] == call and (fill is None or x["fill"] == fill))
            excess.append(f"{d / 1e6:+.1f}")
        print(f"| {v['scene']} | {v['frame_ms']:.1f} | {v['embree_frame_ms']:.1f} | "
              f"{v['embree_frame_ms'] / v['frame_ms']:.2f} | {r / 1e6:.1f} | {e / 1e6:.1f} | {ratio(e, r)} | "
              f"{rest_r / 1e6:.1f} | {rest_e / 1e6:.1f} | " + " | ".join(excess) + " |")
    for v in views:
        print(f"\n## {v['scene']}\n")
        print(f"{v.get('triangles', 0):,} triangles; {v.get('primary_rays', 0):,} primary, "
              f"{v.get('shadow_rays', 0):,} shadow and {v.get('reflection_rays', 0):,} mirror rays a frame; "
              f"counter {v.get('trace_ticks_tsc_ghz', 0.0):.2f} GHz.\n")
        print("| call | rtc M ticks | ticks/call | rays/call | Embree M ticks | ticks/call | Embree / rtc |")
        print("|---|---:|---:|---:|---:|---:|---:|")
        for x in v["trace_ticks"]:
            a, b = side(x, "rtc"), side(x, "embree")
            per_a = a["ticks_per_frame"] / a["calls_per_frame"] if a["calls_per_frame"] else 0.0
            per_b = b["ticks_per_frame"] / b["calls_per_frame"] if b["calls_per_frame"] else 0.0
            rays = a["rays_per_frame"] / a["calls_per_frame"] if a["calls_per_frame"] else 0.0
            print(f"| {x['name']} | {a['ticks_per_frame'] / 1e6:.2f} | {per_a:,.0f} | {rays:.2f} | "
                  f"{b['ticks_per_frame'] / 1e6:.2f} | {per_b:,.0f} | {ratio(b['ticks_per_frame'], a['ticks_per_frame'])} |")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: summarize_trace_ticks.py RESULTS.jsonl")
    main(sys.argv[1])
