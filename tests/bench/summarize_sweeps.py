#!/usr/bin/env python3
"""Summarises tests/bench/results/sweep/<scene>/{sweep.csv,reference.json} as Markdown: per
scene, the reference, the shipped default's time and error, and the cheapest and most accurate
points of the Pareto front.

usage: summarize_sweeps.py SWEEP_DIR
"""
import csv
import json
import os
import sys


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    root = sys.argv[1]
    scenes = sorted(d for d in os.listdir(root) if os.path.isfile(os.path.join(root, d, "sweep.csv")))
    if not scenes:
        sys.exit(f"summarize_sweeps: no <scene>/sweep.csv under {root}")
    print("# Run time against error on the shared scenes (rtc-bench --sweep)\n")
    print("Regenerate with `tests/bench/run_sweeps.sh`. Error is measured against a double-precision reference "
          "render (depth 64, no weight cutoff) on sRGB-encoded pixels clamped to [0, 1]; time is one frame from "
          "scratch: kd-tree build + render (2 threads) + tile encode/decode + sending the tiles over a 100 Mbit/s "
          "link. `>1/255` = % of pixels with a channel off by more than one 8-bit step.\n")
    print("| scene | tris | reference ms | reference vs Embree | default: total ms | RMSE | PSNR dB | max err | >1/255 "
          "| depth 0: RMSE | most accurate setting | its RMSE | >1/255 | settings on the front |")
    print("|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|")
    for s in scenes:
        with open(os.path.join(root, s, "sweep.csv"), newline="") as f:
            rows = list(csv.DictReader(f))
        with open(os.path.join(root, s, "reference.json")) as f:
            ref = json.load(f)
        d = next(r for r in rows if r["is_default"] == "1")
        best = min(rows, key=lambda r: (float(r["rmse"]), float(r["total_ms"])))
        depth0 = next((r for r in rows if r["setting"] == "max depth 0"), None)
        vis = ref.get("embree_visibility", {})
        vis_text = (f"{100 * vis['hit_miss_agreement']:.4f}% hit/miss, {vis['unexplained']} unexplained"
                    if vis else "not checked")
        front = sum(1 for r in rows if r["pareto"] == "1")
        print(f"| {s} | {ref['triangles']:,} | {ref['render_ms']:.0f} | {vis_text} | {float(d['total_ms']):.1f} | "
              f"{float(d['rmse']):.2e} | {float(d['psnr_db']):.1f} | {float(d['max_abs']):.3f} | "
              f"{float(d['pct_over_1_255']):.3f}% | {float(depth0['rmse']) if depth0 else float('nan'):.2e} | "
              f"{best['setting']} | {float(best['rmse']):.2e} | {float(best['pct_over_1_255']):.3f}% | {front} |")
    print()
    for s in scenes:
        with open(os.path.join(root, s, "sweep.csv"), newline="") as f:
            rows = list(csv.DictReader(f))
        print(f"## {s}\n")
        print("| group | setting | default | front | build ms | render ms | codec ms | bytes | link ms | total ms | "
              "RMSE | PSNR | max err | >1/255 | NaN/Inf |")
        print("|---|---|:-:|:-:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        for r in rows:
            print(f"| {r['group']} | {r['setting']} | {'yes' if r['is_default'] == '1' else ''} | "
                  f"{'yes' if r['pareto'] == '1' else ''} | {float(r['build_ms']):.1f} | {float(r['render_ms']):.1f} | "
                  f"{float(r['codec_ms']):.1f} | {int(r['wire_bytes']):,} | {float(r['link_ms_100mbit']):.1f} | "
                  f"{float(r['total_ms']):.1f} | {float(r['rmse']):.2e} | {float(r['psnr_db']):.1f} | "
                  f"{float(r['max_abs']):.3f} | {float(r['pct_over_1_255']):.3f}% | {r['non_finite']} |")
        print()


if __name__ == "__main__":
    main()
