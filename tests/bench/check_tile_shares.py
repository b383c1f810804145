#!/usr/bin/env python3
"""ctest check of rtc-bench --tiles (label integration), on the built-in scene at 200x100 (so
that the right column and bottom row of tiles are partial): a share of the image's 16x16 tiles
traced by every side alike.
  - the JSON line names the share, and its rays are exactly the pixels of those tiles (counted
    here from the image's size, tiles in rows); three shares that cover the image add up to all
    its pixels;
  - the hits and the occlusion are compared with Embree's over those pixels only (the agreement
    line's ray count);
  - shares that are not FROM:TO with 0 <= FROM < TO <= 1 or that hold no tile, and --tiles with
    the full mode, --sweep or --dump, are refused with a message naming --tiles (or --dump);
  - summarize_tile_shares.py tabulates a share's figures and a stats build's footprint.

usage: check_tile_shares.py RTC_BENCH
"""
import json
import math
import os
import re
import subprocess
import sys
import tempfile

from bench_checks import bench_json, check, failures, finite_positive

TILE = 16


def share_pixels(width, height, start, end):
    tx, ty = math.ceil(width / TILE), math.ceil(height / TILE)
    n = tx * ty
    first, last = min(n, math.floor(start * n + 1e-9)), min(n, math.floor(end * n + 1e-9))
    total = 0
    for t in range(first, last):
        x0, y0 = (t % tx) * TILE, (t // tx) * TILE
        total += min(TILE, width - x0) * min(TILE, height - y0)
    return total


def main(bench):
    common = ["--threads", "1", "--reps", "1", "--build-reps", "1", "--width", "200", "--height", "100"]
    stdout, rows = bench_json(bench, common + ["--mode", "primary", "--mode", "shadow", "--compare-embree",
                                               "--tiles", "0.25:0.5"])
    check(sorted(r.get("mode") for r in rows) == ["primary", "shadow"], f"modes {[r.get('mode') for r in rows]}")
    primary = next((r for r in rows if r.get("mode") == "primary"), None)
    if primary is not None:
        width, height = primary["width"], primary["height"]
        check((width, height) == (200, 100), f"image {width}x{height}")
        want = share_pixels(width, height, 0.25, 0.5)
        check(0 < want < width * height, f"the share holds {want} of {width * height} pixels")
        check(primary.get("tiles") == [0.25, 0.5], f"tiles {primary.get('tiles')}")
        check(primary.get("rays") == want, f"primary rays {primary.get('rays')}, the share's pixels {want}")
        for key in ("mrays_per_s", "embree_best_mrays_per_s", "ratio_vs_embree_best_paired"):
            check(finite_positive(primary.get(key)), f"primary {key} = {primary.get(key)}")
        for name, m in primary.get("embree", {}).items():
            check(m.get("hit_miss_agreement", 0) > 0.999, f"primary {name}: agreement {m.get('hit_miss_agreement')}")
        shadow = next((r for r in rows if r.get("mode") == "shadow"), {})
        check(shadow.get("tiles") == [0.25, 0.5], f"shadow tiles {shadow.get('tiles')}")
        check(len(shadow.get("embree", {})) > 0, "shadow: no Embree figures")
        for name, m in shadow.get("embree", {}).items():
            check(m.get("occlusion_agreement", 0) > 0.999, f"shadow {name}: agreement {m.get('occlusion_agreement')}")
        # Three shares covering the image: all its pixels, once.
        total = 0
        for share in ("0:0.3", "0.3:0.7", "0.7:1"):
            _, part = bench_json(bench, common + ["--mode", "primary", "--tiles", share])
            total += part[0].get("rays", 0) if part else 0
        check(total == width * height, f"three shares' rays {total}, the image's pixels {width * height}")
        # The agreement with Embree is over the share's pixels, not the image's.
        text = subprocess.run([bench, *common, "--mode", "primary", "--compare-embree", "--tiles", "0.25:0.5"],
                              capture_output=True, text=True, timeout=240)
        counted = re.search(r"agreement: (\d+) rays", text.stdout)
        check(counted is not None and int(counted.group(1)) == want,
              f"agreement over {counted.group(1) if counted else '?'} rays, the share's {want}")
        # The summary: the share's row, with a footprint from a (made-up) stats-build line.
        stats = dict(primary)
        for key in ("ratio_vs_embree_best_paired", "embree", "embree_best_mrays_per_s"):
            stats.pop(key, None)
        stats["footprint_packets"] = {"node_lines": 15625, "record_lines": 31250}
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "shares.jsonl")
            with open(path, "w") as f:
                f.write(json.dumps(primary) + "\n" + json.dumps(stats) + "\n")
            summary = subprocess.run([sys.executable, os.path.join(os.path.dirname(__file__),
                                                                   "summarize_tile_shares.py"), path],
                                     capture_output=True, text=True)
            check(summary.returncode == 0, f"summarize_tile_shares.py: {summary.stderr[-2000:]}")
            row = f"| {primary['scene']} | 0.25-0.5 | {want:,} | 1.00 | 2.00 | {primary['mrays_per_s']:.2f} | "
            row += f"{primary['embree_best_mrays_per_s']:.2f} ({primary['embree_best_mode']}) | "
            row += f"{primary['ratio_vs_embree_best_paired']:.2f} | - | - | - |"
            check(row in summary.stdout, f"summary row {row!r} not in:\n{summary.stdout}")
            with open(path, "w") as f:
                old = dict(primary)
                old.pop("tiles")
                f.write(json.dumps(old) + "\n")
            refused = subprocess.run([sys.executable, os.path.join(os.path.dirname(__file__),
                                                                   "summarize_tile_shares.py"), path],
                                     capture_output=True, text=True)
            check(refused.returncode != 0 and "tile share" in refused.stderr,
                  f"a line without the share: exit {refused.returncode}, {refused.stderr!r}")
    for args, word in ((["--tiles", "0.5"], "--tiles"), (["--tiles", "0.5:0.25"], "--tiles"),
                       (["--tiles", "-0.1:0.5"], "--tiles"), (["--tiles", "0:1.5"], "--tiles"),
                       (["--tiles", "0.1:0.2x"], "--tiles"), (["--tiles", "0:0.5", "--mode", "full"], "--tiles"),
                       (["--tiles", "0.5:0.5001", "--mode", "primary"], "--tiles"),
                       (["--tiles", "0:0.5", "--mode", "primary", "--sweep", "/nonexistent/x"], "--tiles"),
                       (["--tiles", "0:0.5", "--mode", "primary", "--dump", "/nonexistent/x"], "--dump")):
        run = subprocess.run([bench, *common, *args], capture_output=True, text=True, timeout=120)
        check(run.returncode != 0 and word in run.stderr, f"{args}: exit {run.returncode}, stderr {run.stderr!r}")
    if failures:
        print(f"{len(failures)} check(s) failed")
        return 1
    print("rtc-bench --tiles: all checks passed")
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: check_tile_shares.py RTC_BENCH")
    sys.exit(main(sys.argv[1]))
