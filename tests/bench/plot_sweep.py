#!/usr/bin/env python3
"""Plots rtc-bench --sweep output: time per frame against error, one colour per group of
settings, the Pareto front as a line, the shipped default circled. Draws with gnuplot
(Debian's gnuplot-nox, installed by deploy/install-deps.sh).

usage: plot_sweep.py SWEEP.csv OUT.png [--title TEXT]
"""
import argparse
import csv
import os
import shutil
import subprocess
import sys
import tempfile


def nice_tics(lo, hi):
    """1-2-3-5 steps per decade between lo and hi, as a gnuplot tic list."""
    import math
    out = []
    for e in range(math.floor(math.log10(lo)) - 1, math.ceil(math.log10(hi)) + 1):
        for m in (1, 2, 3, 5):
            v = m * 10.0 ** e
            if lo <= v <= hi:
                out.append(f'"{v:g}" {v:g}')
    return "(" + ", ".join(out) + ")"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("csv")
    ap.add_argument("png")
    ap.add_argument("--title", default=None)
    args = ap.parse_args()

    try:
        with open(args.csv, newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError as e:
        sys.exit(f"plot_sweep: {args.csv}: {e.strerror}")
    need = {"group", "setting", "is_default", "pareto", "total_ms", "rmse"}
    if not rows or not need.issubset(rows[0].keys()):
        sys.exit(f"plot_sweep: {args.csv}: not an rtc-bench --sweep CSV (needs columns {sorted(need)})")
    gnuplot = shutil.which("gnuplot")
    if gnuplot is None:
        sys.exit("plot_sweep: gnuplot not found; install it with deploy/install-deps.sh (package gnuplot-nox)")

    groups = []
    for r in rows:
        if r["group"] not in groups:
            groups.append(r["group"])
    with tempfile.TemporaryDirectory() as tmp:
        files = {}
        for i, g in enumerate(groups):
            path = os.path.join(tmp, f"group{i}.dat")
            with open(path, "w") as f:
                for r in rows:
                    if r["group"] == g:
                        f.write(f'{float(r["rmse"]):.6e} {float(r["total_ms"]):.4f}\n')
            files[g] = path
        front = sorted((float(r["rmse"]), float(r["total_ms"]), r["setting"]) for r in rows if r["pareto"] == "1")
        front_path = os.path.join(tmp, "front.dat")
        with open(front_path, "w") as f:
            for e, t, name in front:
                f.write(f'{e:.6e} {t:.4f} "{name}"\n')
        default = [r for r in rows if r["is_default"] == "1"]
        default_path = os.path.join(tmp, "default.dat")
        with open(default_path, "w") as f:
            for r in default:
                f.write(f'{float(r["rmse"]):.6e} {float(r["total_ms"]):.4f}\n')

        title = args.title or f"rtc time against error ({os.path.basename(os.path.dirname(os.path.abspath(args.csv)))})"
        script = [
            "set terminal pngcairo enhanced size 1200,800 font 'sans,11'",
            f"set output '{args.png}'",
            f"set title '{title}'",
            "set logscale xy",
            f"set yrange [{min(float(r['total_ms']) for r in rows) * 0.85:.4g}:{max(float(r['total_ms']) for r in rows) * 1.15:.4g}]",
            f"set xrange [{min(float(r['rmse']) for r in rows) * 0.8:.4g}:{max(float(r['rmse']) for r in rows) * 1.25:.4g}]",
            "set ytics " + nice_tics(min(float(r['total_ms']) for r in rows) * 0.85, max(float(r['total_ms']) for r in rows) * 1.15),
            "set xtics " + nice_tics(min(float(r['rmse']) for r in rows) * 0.8, max(float(r['rmse']) for r in rows) * 1.25),
            "set xlabel 'RMSE against the double-precision reference (sRGB-encoded, 0..1)'",
            "set ylabel 'time for one frame from scratch, ms (build + render + codec + 100 Mbit/s link)'",
            "set key outside right top",
            "set grid",
            "set datafile separator whitespace",
        ]
        plots = []
        for i, g in enumerate(groups):
            plots.append(f"'{files[g]}' using 1:2 with points pt {5 + (i % 8)} ps 1.4 title '{g}'")
        plots.append(f"'{front_path}' using 1:2 with steps lw 2 lc rgb 'black' title 'Pareto front'")
        plots.append(f"'{front_path}' using 1:2:3 with labels offset char 1,0.6 left font 'sans,8' notitle")
        plots.append(f"'{default_path}' using 1:2 with points pt 6 ps 4 lw 3 lc rgb 'red' title 'shipped default'")
        script.append("plot " + ", \\\n     ".join(plots))
        script_path = os.path.join(tmp, "plot.gp")
        with open(script_path, "w") as f:
            f.write("\n".join(script) + "\n")
        res = subprocess.run([gnuplot, script_path], capture_output=True, text=True)
        if res.returncode != 0:
            sys.exit(f"plot_sweep: gnuplot failed: {res.stderr.strip()}")
    print(f"plot_sweep: wrote {args.png} ({len(rows)} settings, {len(front)} on the Pareto front)")


if __name__ == "__main__":
    main()
