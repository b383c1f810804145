#!/usr/bin/env python3
"""summarize_trace_ticks.py on made-up rtc-bench lines with known answers: the per-frame sums,
the rest of each frame, rtc's excess per class of call, and its refusals (no counter rate, more
than one thread, no tally, no Embree renderer)."""
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
SUMMARIZE = os.path.join(HERE, "summarize_trace_ticks.py")


def row(name, call, light, fill, rtc, embree, calls=1000.0, rays=16000.0):
    r = {"name": name, "call": call, "light": light, "fill": fill}
    if rtc is not None:
        r["rtc"] = {"ticks_per_frame": rtc, "calls_per_frame": calls, "rays_per_frame": rays}
    if embree is not None:
        r["embree"] = {"ticks_per_frame": embree, "calls_per_frame": calls, "rays_per_frame": rays}
    return r


def view(**over):
    v = {"mode": "full", "scene": "made-up", "cpu": "test CPU", "threads": 1, "triangles": 10, "primary_rays": 100,
         "shadow_rays": 50, "reflection_rays": 0, "frame_ms": 10.0, "embree_frame_ms": 12.0,
         "trace_ticks_tsc_ghz": 2.0,
         "trace_ticks": [row("primary, 16 of 16 lanes", 0, -1, 0, 8e6, 9e6),
                         row("shadow, light 0, 16 of 16 lanes", 2, 0, 0, 3e6, 2e6),
                         row("shadow, light 1, 16 of 16 lanes", 2, 1, 0, 1e6, 1.5e6),
                         row("shadow, light 0, 1-8 of 16 lanes", 2, 0, 2, 2e6, 1e6, rays=4000.0)]}
    v.update(over)
    return v


def run(lines):
    with tempfile.NamedTemporaryFile("w", suffix=".jsonl", delete=False) as f:
        for line in lines:
            f.write(json.dumps(line) + "\n")
        path = f.name
    try:
        return subprocess.run([sys.executable, SUMMARIZE, path], capture_output=True, text=True)
    finally:
        os.unlink(path)


def main():
    failures = []

    def check(ok, what):
        if not ok:
            failures.append(what)

    out = run([view()])
    check(out.returncode == 0, f"a good file is summarised (exit {out.returncode}: {out.stderr.strip()})")
    summary = [line for line in out.stdout.splitlines() if line.startswith("| made-up |")]
    check(len(summary) == 1, "one summary row names the view")
    if summary:
        cells = [c.strip() for c in summary[0].strip("|").split("|")]
        # frame 10 ms / 12 ms; trace calls 14 / 13.5 M ticks; rest 10 ms * 2 GHz = 20 M less 14 = 6.0,
        # 24 M less 13.5 = 10.5; excess primary 8 - 9 = -1.0, mirror 0, shadow all lanes (3 + 1) -
        # (2 + 1.5) = +0.5, more than half 0, at most half 2 - 1 = +1.0.
        want = ["made-up", "10.0", "12.0", "1.20", "14.0", "13.5", "0.964", "6.0", "10.5", "-1.0", "+0.0", "+0.5",
                "+0.0", "+1.0"]
        check(cells == want, f"summary row {cells} is {want}")
    check("| shadow, light 0, 1-8 of 16 lanes | 2.00 | 2,000 | 4.00 | 1.00 | 1,000 | 0.500 |" in out.stdout,
          "a per-view row gives both sides' M ticks and ticks per call, rays per call and the ratio")

    for what, line in (("no counter rate", {k: v for k, v in view().items() if k != "trace_ticks_tsc_ghz"}),
                       ("two threads", view(threads=2)),
                       ("no tally", {k: v for k, v in view().items() if k != "trace_ticks"}),
                       ("no Embree renderer", {k: v for k, v in view().items() if k != "embree_frame_ms"})):
        bad = run([view(), line])
        check(bad.returncode != 0 and "summarize_trace_ticks:" in bad.stderr,
              f"{what}: refused with a message (exit {bad.returncode}: {bad.stderr.strip()})")
    empty = run([])
    check(empty.returncode != 0, "an empty file is refused")

    for f in failures:
        print("FAIL:", f)
    print(f"{'FAILED' if failures else 'ok'}: summarize_trace_ticks.py checks")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
