#!/usr/bin/env python3
"""Turns rtc-bench --json lines into the Markdown tables of tests/bench/results/."""
import json
import sys
from collections import defaultdict


def main(path):
    rows = [json.loads(line) for line in open(path) if line.strip()]
    by = defaultdict(dict)
    for r in rows:
        by[(r["scene"], r["width"], r["height"], r["threads"])][r["mode"]] = r
    cpu = "machine: see the closing note; figures are medians over the reps"
    print(f"# rtc-bench --compare-embree on the shared scenes\n\n{cpu}. Mrays/s; ratio = rtc 4-wide packets / Embree's fastest mode.\n")
    print("| scene | tris | thr | rtc build ms | Embree build ms (med / high) | primary rtc | primary rtc single | Embree 1 / 4 / 8 / 16 | ratio | shadow rtc | Embree best | ratio | full frame ms | full Mrays/s | hit/miss agree | ties (edge) |")
    print("|---|---:|---:|---:|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for (scene, w, h, thr), modes in sorted(by.items(), key=lambda kv: (kv[1].get("primary", {}).get("triangles", 0), kv[0])):
        p, s, f = modes.get("primary", {}), modes.get("shadow", {}), modes.get("full", {})
        emb = p.get("embree", {})
        em = " / ".join(f'{emb[k]["mrays_per_s"]:.1f}' if k in emb else "-" for k in ("embree-1", "embree-4", "embree-8", "embree-16"))
        agree = emb.get("embree-1", {}).get("hit_miss_agreement", float("nan"))
        ties = emb.get("embree-1", {}).get("ties", 0)
        print(f'| {scene} | {p.get("triangles", 0):,} | {thr} | {p.get("build_ms", 0):.0f} | '
              f'{p.get("embree_build_ms", 0):.0f} / {p.get("embree_build_hq_ms", 0):.0f} | '
              f'{p.get("mrays_per_s", 0):.2f} | {p.get("mrays_per_s_single", 0):.2f} | {em} | {p.get("ratio_vs_embree_best", 0):.2f} | '
              f'{s.get("mrays_per_s", 0):.2f} | {s.get("embree_best_mrays_per_s", 0):.2f} | {s.get("ratio_vs_embree_best", 0):.2f} | '
              f'{f.get("frame_ms", 0):.0f} | {f.get("mrays_per_s", 0):.2f} | {100 * agree:.4f}% | {ties} |')


if __name__ == "__main__":
    main(sys.argv[1])
