#!/usr/bin/env python3
"""Turns tests/bench/cluster_bench.sh's JSON lines into a Markdown table."""
import json
import sys


def with_cases(rows, *kinds):
    """Each summary row after a row of every kind in `kinds`, with the latest of each before it."""
    latest = {}
    for r in rows:
        if r["type"] in kinds:
            latest[r["type"]] = r
        elif r["type"] == "summary" and len(latest) == len(kinds):
            yield (*(latest[k] for k in kinds), r)


def master_ms_per_frame(r):
    """The two table cells of the master's CPU a frame: its network thread's, then the process's."""
    frames = max(r["frames"], 1)
    return f"{1e3 * r['master_io_cpu_s'] / frames:.1f} | {1e3 * r['master_process_cpu_s'] / frames:.1f}"


def main(path):
    rows = [json.loads(line) for line in open(path) if line.strip()]
    out = []
    if any(r.get("type") == "tiles" for r in rows):
        out.append("| size | tile | wire | compress | MB/frame | median fps | master network thread ms/frame | master CPU ms/frame |")
        out.append("|---:|---:|---|---|---:|---:|---:|---:|")
        for case, r in with_cases(rows, "tiles"):
            out.append(f"| {case['size']} | {case['tile']} | {case['wire']} | {case['compress']} | "
                       f"{r['median_bytes_per_frame'] / 1e6:.3f} | {r['median_fps']:.2f} | {master_ms_per_frame(r)} |")
    elif any(r.get("type") == "write" for r in rows):
        out.append("| size | tile | frames in flight | written as | frames | whole run s | median fps | master network thread ms/frame | master CPU ms/frame |")
        out.append("|---:|---:|---:|---|---:|---:|---:|---:|---:|")
        for case, r in with_cases(rows, "write"):
            out.append(f"| {case['size']} | {case['tile']} | {case['in_flight']} | {case['format']} | {r['frames']} | "
                       f"{r['total_s']:.2f} | {r['median_fps']:.2f} | {master_ms_per_frame(r)} |")
    elif any(r.get("type") == "render" for r in rows):
        out.append("| scene | threads = workers | rtc-render fps (render only) | rtc-render fps (incl. PNG write) | cluster median fps | cluster / rtc-render |")
        out.append("|---|---:|---:|---:|---:|---:|")
        for render, case, r in with_cases(rows, "render", "cluster"):
            ratio = r["median_fps"] / render["median_fps_render_only"] if render["median_fps_render_only"] else 0
            out.append(f"| {case['scene']} | {case['workers']} | {render['median_fps_render_only']:.2f} | "
                       f"{render['median_fps_with_write']:.2f} | {r['median_fps']:.2f} | {ratio:.2f} |")
    else:
        out.append("| scene | size | wire | compress | MB/frame | ratio | link | bound fps | achieved fps | achieved / bound |")
        out.append("|---|---:|---|---|---:|---:|---|---:|---:|---:|")
        for case, r in with_cases(rows, "case"):
            bound = r["median_bound_fps"]
            link = f"{r['link_mbit_per_s']:.1f} Mbit/s {r['link_source']}"
            if r.get("link_line_mbit_per_s"):
                link = f"{r['link_mbit_per_s']:.1f} of {r['link_line_mbit_per_s']:.1f} Mbit/s {r['link_source']}"
            out.append(f"| {case['scene']} | {case['size']} | {case['wire']} | {case['compress']} | "
                       f"{r['median_bytes_per_frame'] / 1e6:.3f} | {r['compression_ratio']:.2f} | {link} | "
                       f"{bound:.2f} | {r['median_fps']:.2f} | {r.get('achieved_vs_bound', r['median_fps'] / bound if bound else 0):.2f} |")
    print("\n".join(out))


if __name__ == "__main__":
    main(sys.argv[1])
