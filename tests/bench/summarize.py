#!/usr/bin/env python3
"""Turns rtc-bench --json lines into the Markdown tables of tests/bench/results/.

One table per scene (as the tracer issue's closing note asks): triangles, build time (rtc vs
Embree), primary and shadow M rays/s for each rtc ISA and each Embree mode, the ratio to
Embree's best, and full-frame ms beside the Embree renderer with the same shading. A summary
table of the ratios over all scenes comes first, then the issue's targets: on how many rows each
holds and where it does not.

Lines carry the sweep they came from ("run", run_shared_scenes.sh's RUNS; lines without one are
one run). Each figure is the median over the runs of that scene, thread count and mode (each
run's figure is already rtc-bench's median over its reps); ratios are medians of the per-run
ratios, each taken within one process, and the summary gives their range over the runs.
"""
import json
import os
import statistics
import sys
from collections import defaultdict

ISAS = ("sse4.2", "avx2", "avx512")
EMBREE = ("embree-1", "embree-4", "embree-8", "embree-16")


def fmt(x, digits=2):
    return "-" if x is None else f"{x:.{digits}f}"


def isa_figure(row, isa):
    return row.get("isas", {}).get(isa, {}).get("mrays_per_s")


def median_row(runs):
    """One row whose every number is the median of that number over the runs' rows (nested
    objects too); anything else (names, flags) is the first run's."""
    first = runs[0]
    if isinstance(first, dict):
        return {k: median_row([r[k] for r in runs if isinstance(r, dict) and k in r]) for k in first}
    if isinstance(first, (int, float)) and not isinstance(first, bool):
        values = [r for r in runs if isinstance(r, (int, float)) and not isinstance(r, bool)]
        # Counts (triangles, nodes, rays) stay whole numbers.
        return statistics.median_low(values) if all(isinstance(v, int) for v in values) else statistics.median(values)
    return first


# rtc against Embree: since 2026-11-24 rtc-bench times the contenders in turn, round by round,
# and reports the median of each round's ratio ("..._paired"); older lines have only the ratio
# of the medians, taken one contender after another.
RATIO_KEYS = {
    "primary": ("ratio_vs_embree_best_paired", "ratio_vs_embree_best"),
    "shadow": ("ratio_vs_embree_best_paired", "ratio_vs_embree_best"),
    "full": ("ratio_vs_embree_frame_paired", "ratio_vs_embree_frame"),
}


def ratio(row, mode):
    """The row's ratio to Embree for `mode`: paired by round where it has one, else of medians."""
    for key in RATIO_KEYS[mode]:
        if row.get(key):
            return row[key]
    return None


def build_ratio(row):
    """rtc's build time over Embree's high-quality build: paired by round where the row has it."""
    if row.get("build_vs_embree_hq_paired"):
        return row["build_vs_embree_hq_paired"]
    hq = row.get("embree_build_hq_ms", 0)
    return row.get("build_ms", 0) / hq if hq else None


def span(runs, mode):
    """The range of runs' ratio to Embree for `mode` as " (a-b)" (or "" for one run)."""
    values = [v for v in (ratio(r, mode) for r in runs) if v is not None]
    if len(values) < 2:
        return ""
    return f" ({min(values):.2f}-{max(values):.2f})"


# The tracer issue's targets, checked row by row: (name, the rows' value, whether it meets the
# target, how the value prints). A build's s/M is the 2-thread row's (the 2-core
# machine); the rest hold at 1 and 2 threads.
def seconds_per_million(row):
    tris = row.get("triangles", 0)
    return row.get("build_ms", 0) / 1e3 / tris * 1e6 if tris else None


TARGETS = (
    ("primary rays at least 1.0x Embree's fastest mode", "primary", lambda r: ratio(r, "primary"),
     lambda v: v >= 1.0, "{:.2f}x", (1, 2)),
    ("shadow rays at least 1.0x Embree's fastest occlusion mode", "shadow", lambda r: ratio(r, "shadow"),
     lambda v: v >= 1.0, "{:.2f}x", (1, 2)),
    ("full Whitted frame faster than the Embree renderer", "full", lambda r: ratio(r, "full"),
     lambda v: v > 1.0, "{:.2f}x", (1, 2)),
    ("build at most 0.5 s per million triangles (2 threads)", "primary", seconds_per_million,
     lambda v: v <= 0.5, "{:.3f} s/M", (2,)),
    ("build within 2x Embree's high-quality build", "primary", build_ratio, lambda v: v <= 2.0, "{:.2f}x", (1, 2)),
)


def print_targets(by, scenes):
    """Per target: on how many of the rows it holds, and the rows where it does not."""
    print("## Targets\n")
    print("| target | met | missed (scene, threads: value) |")
    print("|---|---:|---|")
    for name, mode, value, ok, text, threads in TARGETS:
        met, total, missed = 0, 0, []
        for scene in scenes:
            for thr in threads:
                row = by.get((scene, thr), {}).get(mode)
                v = value(row) if row else None
                if v is None:
                    continue
                total += 1
                if ok(v):
                    met += 1
                else:
                    missed.append(f"{scene}, {thr}: {text.format(v)}")
        print(f"| {name} | {met} of {total} | {'; '.join(missed) if missed else 'none'} |")
    print()


def main(path):
    rows = [json.loads(line) for line in open(path) if line.strip()]
    grouped = defaultdict(list)
    for r in rows:
        grouped[(r["scene"], r["threads"], r["mode"])].append(r)
    runs = max(len(v) for v in grouped.values())
    by = defaultdict(dict)
    spans = {}
    for (scene, threads, mode), group in grouped.items():
        by[(scene, threads)][mode] = median_row(group)
        spans[(scene, threads, mode)] = span(group, mode)
    scenes = sorted({k[0] for k in by}, key=lambda s: (min(by[k]["primary"]["triangles"] for k in by if k[0] == s), s))
    any_row = next(iter(rows))
    streams = [r for r in rows if r["mode"] in ("primary", "shadow")]  # the modes with warm-up passes
    print("# rtc-bench --compare-embree on the shared scenes\n")
    # The machine as the run saw it: rtc's widest ISA there, and Embree's widest packet mode.
    vector = "AVX-512" if any_row["isa"] == "avx512" else ("AVX2, no AVX-512" if any_row["isa"] == "avx2" else "SSE4.2")
    embree_isa = "AVX-512" if any("embree-16" in r.get("embree", {}) for r in rows) else "AVX2"
    # The command that regenerates this file: the results' name is the JSON lines' file name.
    name = os.path.splitext(os.path.basename(path))[0]
    command = "tests/bench/run_shared_scenes.sh" + ("" if name == "shared_scenes" and runs == 3 else f" ../shared/scenes 5 {name} {runs}")
    # The CPU as the run recorded it (rtc-bench's "cpu"; runs before 2026-11-29 did not, and were
    # all taken on the 2-core AMD EPYC VM).
    cpu = any_row.get("cpu", "AMD EPYC")
    print(f"Regenerate with `{command}` (one command; 2-core {cpu} with {vector}, Debian 12, "
          f"Embree 3.13.5 from Debian using {embree_isa}). Figures are medians over the reps "
          f"({any_row['reps']} here; builds of a few ms take more rounds, up to 100, until rtc's add up to half a second), then over {runs} run{'s' if runs > 1 else ''} of the whole sweep "
          "(the ratios: medians of each run's ratios, with their range over the runs in brackets in the summary). "
          "Throughput in M rays/s. rtc's headline figure is its best ISA "
          f"({any_row['isa']}); ratio = that / Embree's fastest mode. "
          + ("Within a run every contender (rtc's kernels, Embree's modes; rtc's build and Embree's; rtc's frame "
             "and the Embree renderer's) takes one turn per repetition, and each ratio is paired: the median of the ratios "
             "of the two times taken in the same repetition, so a slow spell of the machine falls on both sides. "
             if any("ratio_vs_embree_best_paired" in r for r in rows) else "")
          + ("In the primary and shadow modes each contender's timed turn follows an untimed pass of its own, so "
             "that it is timed with its own tree or BVH in the caches (rtc-bench's warm-up, since 2026-11-29). "
             if streams and all(r.get("warm_up") for r in streams) else "")
          + "Build: rtc kd-tree vs Embree's BVH at medium (default) and high "
          "quality (high quality in the first 3 repetitions only); s/M = rtc build seconds per million triangles. "
          "Full frame: rtc's Whitted renderer (shadows + "
          "reflections) against the same renderer and shading with every ray traced by Embree's packet calls; "
          "speed > 1 means rtc is faster. Primary rays are timed as traced on both sides; rtc's stream API also "
          "recomputes each hit's distance in double (refine_hit_distances), a step Embree's hits do not get: the "
          "column 't refined' gives rtc's primary figure with it (the headline up to 2026-11-22).\n")
    print("## Summary\n")
    print("| scene | tris | thr | build ms rtc | s/M | Embree high ms | build vs Embree high | primary rtc | t refined | Embree best | ratio | "
          "shadow rtc | Embree best | ratio | full ms rtc | Embree renderer ms | speed |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for scene in scenes:
        for thr in (1, 2):
            modes = by.get((scene, thr))
            if not modes:
                continue
            p, s, f = modes.get("primary", {}), modes.get("shadow", {}), modes.get("full", {})
            tris = p.get("triangles", 0)
            build = p.get("build_ms", 0)
            hq = p.get("embree_build_hq_ms", 0)
            print(f'| {scene} | {tris:,} | {thr} | {build:.0f} | {fmt(seconds_per_million(p))} | {hq:.0f} | '
                  f'{fmt(build_ratio(p))} | {p.get("mrays_per_s", 0):.2f} | {fmt(p.get("mrays_per_s_refined"))} | '
                  f'{p.get("embree_best_mrays_per_s", 0):.2f} | '
                  f'**{fmt(ratio(p, "primary"))}**{spans.get((scene, thr, "primary"), "")} | '
                  f'{s.get("mrays_per_s", 0):.2f} | {s.get("embree_best_mrays_per_s", 0):.2f} | '
                  f'**{fmt(ratio(s, "shadow"))}**{spans.get((scene, thr, "shadow"), "")} | '
                  f'{f.get("frame_ms", 0):.0f} | {f.get("embree_frame_ms", 0):.0f} | '
                  f'**{fmt(ratio(f, "full"))}**{spans.get((scene, thr, "full"), "")} |')
    print()
    print_targets(by, scenes)
    for scene in scenes:
        first = next(by[k] for k in sorted(by) if k[0] == scene)["primary"]
        print(f"## {scene}\n")
        print(f"{first['triangles']:,} triangles, {first['width']}x{first['height']}; kd-tree: {first['kd_nodes']:,} nodes, "
              f"{first['kd_leaves']:,} leaves, depth {first['kd_max_depth']}, {first['kd_tris_per_leaf']:.2f} triangles per "
              f"non-empty leaf, SAH cost {first['kd_sah_cost']:.1f}.\n")
        print("| thr | mode | " + " | ".join(f"rtc {i}" for i in ISAS) + " | rtc single | "
              + " | ".join(EMBREE) + " | ratio to Embree best | agreement |")
        print("|---:|---|" + "---:|" * (len(ISAS) + 1 + len(EMBREE) + 2))
        for thr in (1, 2):
            modes = by.get((scene, thr))
            if not modes:
                continue
            for mode in ("primary", "shadow"):
                r = modes.get(mode)
                if not r:
                    continue
                emb = r.get("embree", {})
                if mode == "primary":
                    agree = emb.get("embree-1", {}).get("hit_miss_agreement")
                    agree_text = "-" if agree is None else f"{100 * agree:.4f}% hit/miss, {emb['embree-1'].get('ties', 0)} ties"
                else:
                    agree = emb.get("embree-1", {}).get("occlusion_agreement")
                    agree_text = "-" if agree is None else f"{100 * agree:.4f}% occlusion"
                print(f"| {thr} | {mode} | " + " | ".join(fmt(isa_figure(r, i)) for i in ISAS)
                      + f" | {fmt(r.get('mrays_per_s_single'))} | "
                      + " | ".join(fmt(emb.get(e, {}).get("mrays_per_s")) for e in EMBREE)
                      + f" | {fmt(ratio(r, mode))} | {agree_text} |")
        for thr in (1, 2):
            modes = by.get((scene, thr))
            if not modes:
                continue
            p, f = modes["primary"], modes.get("full", {})
            print(f"\n{thr} thread{'s' if thr > 1 else ''}: build rtc {p['build_ms']:.0f} ms, Embree "
                  f"{p.get('embree_build_ms', 0):.0f} ms (medium) / {p.get('embree_build_hq_ms', 0):.0f} ms (high); full frame "
                  f"rtc {f.get('frame_ms', 0):.1f} ms ({f.get('primary_rays', 0):,} primary, {f.get('shadow_rays', 0):,} shadow, "
                  f"{f.get('reflection_rays', 0):,} reflection rays), Embree renderer {f.get('embree_frame_ms', 0):.1f} ms, "
                  f"{100 * f.get('embree_frame_pixels_differing', 0):.4f}% of pixels differ by more than 1/255.", end="")
        print("\n")


if __name__ == "__main__":
    main(sys.argv[1])
