#!/usr/bin/env python3
"""Turns tests/bench/run_kd_ab.sh's lines into tests/bench/results/NAME.md.

Usage: summarize_kd_ab.py NAME.txt OPTION NAME
Each line may end with the kernels' ISA in its run (sse4.2, avx2, avx512); lines written before
that field was added are avx512 runs.
Per view: triangles; nodes, SAH and the median build time at each of the option's two values; the
median over rounds of the paired throughput ratio (second value over first, same round) for
each mode in the lines: primary and shadow rays (in packets, and as primary-single and
shadow-single the same rays traced one at a time), and whole Whitted frames (full: rays per
second of the frame, so the ratio is the frame's speed). The values keep the order
run_kd_ab.sh ran them in (first seen first).
"""
import collections
import statistics
import sys


# What each option is, for the title; K_T's SAH costs are not comparable across its values.
OPTIONS = {
    "--kd-traversal-cost": "SAH traversal cost K_T",
    "--kd-mask-below": "bit-mask stage below this many references (--kd-mask-below)",
    "--kd-intersection-cost": "SAH intersection cost K_I",
    "binaries": "two rtc-bench binaries (tests/bench/run_bin_ab.sh), A and B",
}


WIDTH = {"sse4.2": 4, "avx2": 8, "avx512": 16}  # rtc::isa_name's names


def main(path, option, name):
    what = OPTIONS.get(option, option)
    runs = collections.defaultdict(dict)  # (scene, mode, round) -> {value: (mrays, build, nodes, sah, tris)}
    values = []  # in the order the run gave them
    isas = set()
    for line in open(path):
        p = line.split()
        if len(p) not in (9, 10):
            continue
        isas.add(p[9] if len(p) == 10 else "avx512")
        scene, value, rnd, mode = p[0], p[1], p[2], p[3]
        if value not in values:
            values.append(value)
        runs[(scene, mode, rnd)][value] = (float(p[4]), float(p[5]), int(p[6]), float(p[7]), int(p[8]))
    if len(values) != 2:
        sys.exit(f"summarize_kd_ab: expected two values of {option} in {path}, found {values}")
    a, b = values
    if len(isas) != 1:
        sys.exit(f"summarize_kd_ab: the runs in {path} used different ISAs: {sorted(isas)}")
    isa = isas.pop()
    modes = [m for m in ("primary", "shadow", "primary-single", "shadow-single", "full") if any(k[1] == m for k in runs)]
    label = {"primary": "primary", "shadow": "shadow", "primary-single": "single-ray primary",
             "shadow-single": "single-ray shadow", "full": "full frame"}
    scenes = sorted({k[0] for k in runs}, key=lambda s: (min(v[a][4] for k, v in runs.items() if k[0] == s and a in v), s))
    print(f"# {what}: {a} against {b}\n")
    sah_note = ("The SAH cost is computed with the build's own K_T, so it is not comparable across K_T. "
                if option == "--kd-traversal-cost" else
                "The SAH cost is computed with the build's own K_I, so it is not comparable across K_I. "
                if option == "--kd-intersection-cost" else "")
    command = (f"tests/bench/run_bin_ab.sh A B {name}" if option == "binaries" else
               f"tests/bench/run_kd_ab.sh {option} \"{a} {b}\" {name}")
    print(f"`{command}` — rtc-bench on every shared view, one thread, {WIDTH.get(isa, '?')}-wide packets ({isa}), "
          f"process CPU time, `--reps 5 --build-reps 3`, modes {', '.join(modes)} (a -single mode: the same rays traced one at a time), the two values alternating view by view in each round. "
          f"Ratios are {b} over {a}, paired within a round; the median over the rounds comes first, the "
          "single rounds in brackets. Build: median over the rounds of each run's median of 3 builds (flattening plus "
          "kd-tree). " + sah_note + "On this VM one binary's runs vary by 10-15%: a view whose tree did not change (equal node counts) shows that noise.\n")
    print(f"| view | tris | nodes {a} → {b} | SAH {a} → {b} | build ms {a} → {b} | " +
          " | ".join(f"{label[m]} {b}/{a}" for m in modes) + " |")
    print("|---|---:|---|---|---|" + "---|" * len(modes))
    medians = {m: [] for m in modes}
    builds = []
    for s in scenes:
        cells = {}
        for mode in modes:
            pairs = [v for k, v in runs.items() if k[0] == s and k[1] == mode and a in v and b in v]
            ratios = sorted(v[b][0] / v[a][0] for v in pairs)
            cells[mode] = ratios
            medians[mode].append(statistics.median(ratios))
        pairs = [v for k, v in runs.items() if k[0] == s and k[1] == modes[0] and a in v and b in v]
        build_a = statistics.median(v[a][1] for v in pairs)
        build_b = statistics.median(v[b][1] for v in pairs)
        first = pairs[0]
        build_ratio = f" ({build_b / build_a:.2f})" if build_a >= 10 else ""
        if build_a >= 10:
            builds.append(build_b / build_a)
        text = {m: f"{statistics.median(r):.2f} ({', '.join(f'{x:.2f}' for x in r)})" for m, r in cells.items()}
        print(f"| {s} | {first[a][4]:,} | {first[a][2]:,} → {first[b][2]:,} | {first[a][3]} → {first[b][3]} | "
              f"{build_a:.0f} → {build_b:.0f}{build_ratio} | " + " | ".join(text[m] for m in modes) + " |")
    print()
    if not builds:
        builds = [float("nan")]
    parts = [f"{label[m]} {b}/{a} median {statistics.median(medians[m]):.2f} "
             f"(views {min(medians[m]):.2f}-{max(medians[m]):.2f})" for m in modes]
    print(f"Over the views: {', '.join(parts)}; "
          f"builds of 10 ms or more {min(builds):.2f}-{max(builds):.2f}x the time (median {statistics.median(builds):.2f}).")


if __name__ == "__main__":
    if len(sys.argv) != 4:
        sys.exit("usage: summarize_kd_ab.py NAME.txt OPTION NAME")
    main(*sys.argv[1:])
