#!/usr/bin/env python3
"""Markdown table of tests/bench/run_kd_clip.sh's JSON lines: kd-tree perfect splits off/on."""
import json
import statistics
import sys
from collections import defaultdict


def main(path):
    runs = defaultdict(list)  # (scene, clip, mode) -> [record]
    for line in open(path):
        line = line.strip()
        if line:
            r = json.loads(line)
            runs[(r["scene"], r["kd_clip"], r["mode"])].append(r)
    scenes = sorted({k[0] for k in runs}, key=lambda s: (runs[(s, False, "primary")][0]["triangles"], s))
    med = lambda rs, key: statistics.median(r[key] for r in rs)
    any_rec = next(iter(runs.values()))[0]
    print("# kd-tree perfect splits: off (clamped boxes) against on (straddlers clipped)\n")
    print(f"`tests/bench/run_kd_clip.sh` — rtc-bench, {any_rec['threads']} threads, {any_rec['isa']}, "
          f"{any_rec['width']}x{any_rec['height']}, CPU time (`--cpu-time`), medians over alternating runs. Build = flattening + kd-tree. "
          "Full = one Whitted frame (shadows + reflections). Break-even: frames of the scene's own view after "
          "which the slower build has paid for itself (build difference / full-frame difference); "
          "'never' where clipping did not make the frame faster. 'same tree': clipping changed nothing "
          "(no straddler's clipped bounds were smaller), so the two columns differ only by measurement noise.\n")
    print("| scene | tris | build ms off → on | refs off → on (M) | nodes off → on (M) | SAH off → on | "
          "primary Mrays/s off → on | shadow Mrays/s off → on | full frame ms off → on | break-even frames |")
    print("|---|---:|---|---|---|---|---|---|---|---:|")
    for s in scenes:
        p = {c: runs[(s, c, "primary")] for c in (False, True)}
        sh = {c: runs[(s, c, "shadow")] for c in (False, True)}
        fu = {c: runs[(s, c, "full")] for c in (False, True)}
        if not all(p.values()) or not all(sh.values()) or not all(fu.values()):
            continue
        b = {c: med(p[c] + sh[c] + fu[c], "build_ms") for c in (False, True)}
        frame = {c: med(fu[c], "frame_ms") for c in (False, True)}
        gain = frame[False] - frame[True]
        extra = b[True] - b[False]
        if gain <= 0:
            be = "never"
        elif extra <= 0:
            be = "0"
        else:
            be = f"{extra / gain:.0f}"
        r0 = p[False][0]
        r1 = p[True][0]
        if all(r0[k] == r1[k] for k in ("kd_nodes", "kd_refs", "kd_sah_cost")):
            be = "same tree"
        print(f"| {s} | {r0['triangles']:,} | {b[False]:.0f} → {b[True]:.0f} | "
              f"{r0['kd_refs'] / 1e6:.2f} → {r1['kd_refs'] / 1e6:.2f} | {r0['kd_nodes'] / 1e6:.2f} → {r1['kd_nodes'] / 1e6:.2f} | "
              f"{r0['kd_sah_cost']:.1f} → {r1['kd_sah_cost']:.1f} | "
              f"{med(p[False], 'mrays_per_s'):.1f} → {med(p[True], 'mrays_per_s'):.1f} | "
              f"{med(sh[False], 'mrays_per_s'):.1f} → {med(sh[True], 'mrays_per_s'):.1f} | "
              f"{frame[False]:.1f} → {frame[True]:.1f} | {be} |")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: summarize_kd_clip.py KD_CLIP.jsonl")
    main(sys.argv[1])
