#!/usr/bin/env python3
"""Markdown table of tests/bench/run_specialise.sh's JSON lines: general against specialised
kernels, with and without empty-space skipping."""
import json
import statistics
import sys
from collections import defaultdict


def main(path):
    runs = defaultdict(list)  # label -> [record]
    order = []
    for line in open(path):
        line = line.strip()
        if not line:
            continue
        r = json.loads(line)
        if r["label"] not in runs:
            order.append(r["label"])
        runs[r["label"]].append(r)
    first = runs[order[0]][0]
    print("# Kernels specialised to the scene's features, and empty-space skipping\n")
    print(f"`tests/bench/run_specialise.sh` — rtc-bench --kernel-ab, {first['threads']} thread(s), {first['isa']}, "
          f"CPU time (`--cpu-time`). Each run renders the general kernel, the specialised one, and each of them "
          f"skipping empty space, in turn, {first['kernel_ab_reps']} times on one prepared frame, and checks that all "
          "four give the same bits (depth and normal channels included); a figure is the median over runs of "
          "the median paired ratio (that kernel's time / the general kernel's in the same repetition), so "
          "below 1 is faster; [min-max over runs]. Where the specialised kernel is the general one (kernel "
          "'general'), its column measures nothing but the machine's noise.\n")
    print("| view | features | kernel | primary rays skipped | general ms | specialised | general + skip | "
          "specialised + skip | same pixels |")
    print("|---|---|---|---:|---:|---|---|---|---|")
    for label in order:
        rs = runs[label]
        r0 = rs[0]

        def ratio(name):
            v = [r["kernel_ab_ratio"][name] for r in rs]
            return f"{statistics.median(v):.3f} [{min(v):.3f}-{max(v):.3f}]"

        general_ms = statistics.median(r["kernel_ab_ms"]["general"] for r in rs)
        same = all(r["kernel_ab_same_pixels"] for r in rs)
        aovs = "" if r0["aovs"] else ", no AOVs"
        print(f"| {label} | {r0['features']}{aovs} | {r0['kernel']} | {100 * r0['primary_skipped_fraction']:.1f}% | "
              f"{general_ms:.1f} | {ratio('specialised')} | {ratio('general_skip')} | {ratio('specialised_skip')} | "
              f"{'yes' if same else '**NO**'} ({len(rs)} runs) |")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: summarize_specialise.py SPECIALISE.jsonl")
    main(sys.argv[1])
