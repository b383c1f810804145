#!/usr/bin/env python3
"""Temporal-coherence benchmark (tests/bench/run_temporal.sh): parses rtc-render's frame lines
and the master's stats JSON into JSON lines, and turns them into the Markdown table of
tests/bench/results/temporal.md."""
import json
import re
import statistics
import sys

FRAME = re.compile(r"^frame (\d+): wrote .* prepare (\d+) ms \(cpu (\d+) ms\), render (\d+) ms \(cpu (\d+) ms\)")
RETRACED = re.compile(r"\| (\d+)/(\d+) tiles retraced")
ALL = re.compile(r"\| all (\d+) tiles traced")


def parse(name, mode, run):
    for line in sys.stdin:
        m = FRAME.match(line)
        if not m:
            continue
        rec = {"kind": "render", "scene": name, "mode": mode, "run": int(run), "frame": int(m.group(1)),
               "prepare_ms": int(m.group(2)), "prepare_cpu_ms": int(m.group(3)), "render_ms": int(m.group(4)),
               "cpu_ms": int(m.group(5))}
        r = RETRACED.search(line)
        a = ALL.search(line)
        if r:
            rec["traced"], rec["tiles"] = int(r.group(1)), int(r.group(2))
        elif a:
            rec["traced"] = rec["tiles"] = int(a.group(1))
        print(json.dumps(rec))


def cluster(name, mode, stats):
    frames = []
    with open(stats) as f:
        for line in f:
            j = json.loads(line)
            if j.get("type") == "frame":
                frames.append(j)
    for j in sorted(frames, key=lambda x: x["sequence"]):
        t = j.get("temporal", {})
        print(json.dumps({"kind": "cluster", "scene": name, "mode": mode, "frame": j["frame"],
                          "wire_bytes": j["wire_bytes"], "mark_bytes": t.get("mark_bytes", 0),
                          "render_ms": j["render_ms"], "traced": t.get("tiles_traced"),
                          "tiles": t.get("tiles_total")}))


def table(path):
    recs = [json.loads(l) for l in open(path) if l.strip()]
    scenes = []
    for r in recs:
        if r["scene"] not in scenes:
            scenes.append(r["scene"])

    def med(xs):
        return statistics.median(xs) if xs else float("nan")

    print("# Temporal coherence (issue 7): incremental frames against full re-renders\n")
    print("Regenerate with `[TILE=16] [FIRST=15] tests/bench/run_temporal.sh [THREADS] [REPEAT]` (2-core AMD EPYC, Debian 12), "
          "both modes in tiles of TILE pixels (16, what temporal coherence uses by default). Moving meshes are "
          "instanced (their kd-trees built once, in object space), so prepare costs next to nothing after frame 0 "
          "in either mode. Per frame: "
          "time = prepare (kd-trees) + render of `rtc-render`, median over the runs; `--temporal off` traces "
          "every frame whole, `--temporal on` traces frame 0 whole while recording marks, then only the tiles the "
          "tracker finds dirty. Times are process CPU time (steadier than wall time on a shared machine; with "
          "THREADS > 1 summed over the threads). Speed-up = sum over frames 1..N of the full frames' prepare + "
          "render time / the incremental frames', per run (the two renders of a run ran one after the other), "
          "median over the runs [range]; render only leaves prepare out. First-frame overhead = incremental "
          "frame 0 / full frame 0, render CPU time (the cost of marking), from FIRST (15) further runs of the "
          "first two frames alone, alternating: the sum of the incremental frames 0 over the sum of the full "
          "ones [range of the single pairs]. Wire: bytes per frame "
          "the master received (tiles + marks) with 2 workers, frames 1..N.\n")
    print("| animation | frames | tiles | traced per frame (mean, min-max) | full ms/frame | incremental ms/frame | "
          "speed-up | render only | first-frame overhead | wire KB/frame full | incremental | of which marks | saved |")
    print("|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for s in scenes:
        by = {}
        for r in recs:
            if r["scene"] == s and r["kind"] == "render" and not r["mode"].startswith("first-"):
                by.setdefault((r["mode"], r["frame"]), []).append(r)
        frames = sorted({f for (_, f) in by})
        if not frames:
            continue

        def t(mode, f, key):
            return med([x[key] for x in by.get((mode, f), [])])

        later = frames[1:]
        full = sum(t("off", f, "prepare_cpu_ms") + t("off", f, "cpu_ms") for f in later)
        inc = sum(t("on", f, "prepare_cpu_ms") + t("on", f, "cpu_ms") for f in later)
        # Paired per run (run r's full and incremental renders ran one after the other, so they
        # share the machine's state of the moment): the median over runs, and the range.
        runs = sorted({x["run"] for xs in by.values() for x in xs})

        def run_val(mode, f, r, key):
            xs = [x[key] for x in by.get((mode, f), []) if x["run"] == r]
            return xs[0] if xs else None

        speed, speed_r, over_r = [], [], []
        for r in runs:
            vals = {}
            for mode in ("off", "on"):
                p = [run_val(mode, f, r, "prepare_cpu_ms") for f in later]
                c = [run_val(mode, f, r, "cpu_ms") for f in later]
                if None in p or None in c:
                    break
                vals[mode] = (sum(p) + sum(c), sum(c))
            else:
                speed.append(vals["off"][0] / max(vals["on"][0], 1e-9))
                speed_r.append(vals["off"][1] / max(vals["on"][1], 1e-9))
        # First-frame overhead from the runs of the first frames alone (FIRST of them).
        first = {}
        for x in recs:
            if x["scene"] == s and x["kind"] == "render" and x["mode"].startswith("first-") and x["frame"] == frames[0]:
                first.setdefault(x["run"], {})[x["mode"][6:]] = x["cpu_ms"]
        sum_on = sum_off = 0
        for pair in first.values():
            if "on" in pair and pair.get("off"):
                over_r.append(pair["on"] / pair["off"] - 1)
                sum_on += pair["on"]
                sum_off += pair["off"]
        # The ratio of the summed times (of the means): steadier than the median of single-frame
        # ratios, each the quotient of two noisy ~100 ms samples.
        over_sum = sum_on / sum_off - 1 if sum_off else float("nan")

        def rng(xs, fmt, center=None):
            """`center` (default: the median of xs) [min to max]."""
            if not xs:
                return "n/a"
            return fmt(med(xs) if center is None else center) + " [" + fmt(min(xs)) + " to " + fmt(max(xs)) + "]"

        traced = [by[("on", f)][0].get("traced", 0) for f in later if ("on", f) in by]
        tiles = by[("on", frames[0])][0].get("tiles", 0) if ("on", frames[0]) in by else 0
        cl = [r for r in recs if r["scene"] == s and r["kind"] == "cluster"]

        def wire(mode, key="wire_bytes"):
            xs = [r[key] for r in cl if r["mode"] == mode and r["frame"] != frames[0]]
            return sum(xs) / len(xs) / 1024 if xs else float("nan")

        wf, wi, wm = wire("off"), wire("on"), wire("on", "mark_bytes")
        n = len(later)
        print(f"| {s} | {len(frames)} | {tiles} | {statistics.mean(traced):.0f} ({min(traced)}-{max(traced)}) | "
              f"{full / n:.0f} | {inc / n:.0f} | **{rng(speed, lambda v: f'{v:.2f}x')}** | "
              f"{rng(speed_r, lambda v: f'{v:.2f}x')} | {rng(over_r, lambda v: f'{100 * v:+.0f}%', over_sum)} | "
              f"{wf:.0f} | {wi:.0f} | {wm:.1f} | {100 * (1 - wi / wf):.0f}% |")


if __name__ == "__main__":
    if sys.argv[1] == "--parse":
        parse(*sys.argv[2:5])
    elif sys.argv[1] == "--cluster":
        cluster(*sys.argv[2:5])
    else:
        table(sys.argv[2])
