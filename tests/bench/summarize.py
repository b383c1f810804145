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
    print("# rtc-bench --compare-embree on the shared scenes\n")
    print("Regenerate with `tests/bench/run_shared_scenes.sh` (2-core AMD EPYC, SSE4.2 kernels for rtc, Embree 3.13.5 from Debian "
          "using AVX-512). Figures are medians over the reps. Throughput in M rays/s; ratio = rtc 4-wide packets / Embree's fastest "
          "mode; the Embree renderer is rtc's renderer and shading with every ray traced by Embree's 4-wide packet calls "
          "(rtc speed vs it > 1: rtc is faster); ties = pixels where the two tracers hit different triangles at the same "
          "distance (verified: shared edges/vertices, coplanar overlaps, crossing surfaces).\n")
    print("| scene | tris | thr | rtc build ms | Embree build ms (med / high) | primary rtc | primary rtc single | Embree 1 / 4 / 8 / 16 | ratio | shadow rtc | Embree best | ratio | full frame ms | full Mrays/s | Embree-renderer frame ms | rtc speed vs it | hit/miss agree | ties |")
    print("|---|---:|---:|---:|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
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
              f'{f.get("frame_ms", 0):.0f} | {f.get("mrays_per_s", 0):.2f} | {f.get("embree_frame_ms", 0):.0f} | '
              f'{f.get("ratio_vs_embree_frame", 0):.2f} | {100 * agree:.4f}% | {ties} |')


if __name__ == "__main__":
    main(sys.argv[1])
