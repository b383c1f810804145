#!/usr/bin/env python3
"""ctest check of rtc-bench --sweep (labels stress): runs a quick sweep of one scene and asserts
what must hold whatever the machine's speed:
  - every output of the sweep (and the reference) is free of NaN and Inf (the tool's exit status
    and the non_finite column);
  - the reference's primary visibility agrees with Embree's except at edges and verified ties;
  - settings that trace more are no further from the reference than the shipped default
    (max depth 64 with no cutoff; float pixels), and on a scene with mirrors, dropping the
    reflections (max depth 0) is measurably worse;
  - settings that must not change a pixel (ISA, packets, kd-tree parameters) give exactly the
    default's error;
  - the plot script draws the CSV.

usage: check_sweep.py RTC_BENCH OUT_DIR [SCENE] [--reflective]
"""
import csv
import json
import os
import shutil
import subprocess
import sys

from bench_checks import check, failures


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    reflective = "--reflective" in sys.argv
    if len(args) < 2:
        sys.exit(__doc__)
    bench, out = args[0], args[1]
    scene = args[2] if len(args) > 2 else None
    if scene is not None and not os.path.exists(scene):
        print(f"SKIP: {scene} is absent (the shared scene pack is not here)")
        return 0
    shutil.rmtree(out, ignore_errors=True)
    cmd = [bench] + ([scene] if scene else []) + ["--sweep", out, "--sweep-quick", "--reps", "1",
                                                  "--width", "96", "--height", "72"]
    print("running:", " ".join(cmd), flush=True)
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    print(res.stdout)
    print(res.stderr, file=sys.stderr)
    check(res.returncode == 0, f"rtc-bench --sweep exited {res.returncode}")

    with open(os.path.join(out, "reference.json")) as f:
        ref = json.load(f)
    check(ref["non_finite"] == 0, f"reference has {ref['non_finite']} NaN/Inf values")
    vis = ref["embree_visibility"]
    check(vis["unexplained"] == 0, f"reference vs Embree: {vis['unexplained']} unexplained differences: {vis['summary']}")
    check(vis["hit_miss_agreement"] >= 0.999, f"reference vs Embree hit/miss agreement {vis['hit_miss_agreement']}")

    with open(os.path.join(out, "sweep.csv"), newline="") as f:
        rows = list(csv.DictReader(f))
    by = {r["setting"]: r for r in rows}
    check(len(rows) >= 10, f"only {len(rows)} settings in the sweep")
    for r in rows:
        check(int(r["non_finite"]) == 0, f"{r['setting']}: {r['non_finite']} NaN/Inf values")
    default = [r for r in rows if r["is_default"] == "1"]
    check(len(default) == 1, "exactly one shipped default in the CSV")
    d = default[0]
    rmse = lambda name: float(by[name]["rmse"])
    check(rmse("max depth 64, min weight 0") <= float(d["rmse"]) * (1 + 1e-9),
          "tracing deeper with no cutoff moved further from the reference")
    check(rmse("float zstd") <= float(d["rmse"]) * (1 + 1e-9), "float pixels are further from the reference than rgba8")
    if reflective:
        check(rmse("max depth 0") > 2 * float(d["rmse"]), "dropping reflections did not raise the error on a mirror scene")
    for r in rows:
        if r["group"] in ("packet width / ISA", "kd-tree build"):
            check(r["rmse"] == d["rmse"] and r["max_abs"] == d["max_abs"],
                  f"{r['setting']} changed pixels (RMSE {r['rmse']} vs default {d['rmse']})")

    plot = os.path.join(out, "plot.png")
    res = subprocess.run([sys.executable, os.path.join(os.path.dirname(__file__), "plot_sweep.py"),
                          os.path.join(out, "sweep.csv"), plot], capture_output=True, text=True)
    check(res.returncode == 0 and os.path.getsize(plot) > 1000, f"plot_sweep.py failed: {res.stderr}")

    if failures:
        print(f"{len(failures)} check(s) failed")
        return 1
    print("all sweep checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
