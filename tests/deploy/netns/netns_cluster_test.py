#!/usr/bin/env python3
"""Separate hosts: rtc-master in one network namespace, one rtc-worker in each of 3 more, every
host on its own 100 Mbit/s link to a bridge (netns-cluster.sh). Run inside
with_netns_cluster.sh, which builds the LAN and removes it on every exit path.

usage: netns_cluster_test.py check|table --master M --worker W --render R [--oiiotool O]
         [--keep] [--out FILE] [--frames N] [--sizes 512,1024]

check  the CI test: for each configuration a few frames; every frame equals rtc-render's bit
       for bit, and the master's bandwidth-limited frame rate (from --link-mbps) is within 10%
       of the measured one (frames per second over the master's frame intervals, the first
       frame left out: it includes the start of the pipeline).
table  the frame-rate table (fps_table.sh, results.md): every wire format and compression at
       512x512 and 1024x1024, --frames frames each, traced whole (--temporal off), discarded;
       writes Markdown to --out.

Reuses tests/cluster/cluster_test.py (processes, stats, frame comparison through oiiotool's
pixel hashes). Every wait has a deadline; every process started is killed by pid at the end.
"""

import argparse
import json
import os
import re
import resource
import shutil
import subprocess
import sys
import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "cluster"))
import cluster_test as ct  # noqa: E402  (path set just above)
from cluster_test import fail  # noqa: E402

WORKERS = 3
LINK_MBPS = 100  # the line rate netns-cluster.sh gives each link (with_netns_cluster.sh 3 100mbit)
TOLERANCE = 0.10
# Other machines' load can only slow the cluster (never carry more than the link), so a run
# within 10% shows the bound right; runs disturbed by the host (steal time: 18% of the CPU time
# on this 2-vCPU VM in one check, with frames taking 2x their link time) are run again.
ATTEMPTS = 6

# (label, width, height, frames, wire, compression, file extension, extra args for both
# rtc-master and rtc-render, whether the 10% bound check applies). Float EXR frames carry 32
# bytes a pixel (RGBA, depth, normals): the link needs 0.71 s for a 512x512 frame and 2.85 s
# for 1024x1024, while the master and the three workers keep 0.7-1.0 of the 2 cores busy: both
# are link-bound. Frames of 1024x1024 cost the least CPU per byte, leaving the most room for a
# busy machine, so the 10% check runs on them only: a full CI run from a fresh clone measured
# 512x512 at 0.855, 0.895 and 0.663 of its bound (per frame 1.07-1.42 fps against 1.40) while
# the machine was 66-71% busy; its fixed per-frame costs (each worker's kd-tree rebuild for the
# moving sphere, the frame start) weigh 4x as much against the link time as at 1024x1024. The
# 512x512 frames are still compared bit for bit. The rgba8+zstd case checks the compressed
# path's pixels only: it is CPU-bound here (the link could carry ~300 such frames a second).
# The 1024x1024 case traces every frame whole (--temporal off): with temporal coherence (on by
# default) the frames after the first retrace about an eighth of the tiles, 3.8-4.4 MB in 0.36 s
# of link time, and their fixed costs (each worker's kd-tree rebuild for the moving sphere, the
# frame's first tiles) no longer hide behind the link: on 2026-11-30 they reached 0.84-0.90 of
# the bound in 13 runs of 13, in an hour when this VM ran slow, while the first (whole) frame
# reached 0.96 of its own bound. Whole frames keep the premise of the check, that the link is
# the limit.
CHECKS = [
    ("512x512 float+none", 512, 512, "0-5", "float", "none", "exr", ["--exr-float"], False),
    ("1024x1024 float+none", 1024, 1024, "0-3", "float", "none", "exr", ["--exr-float", *ct.WHOLE], True),
    ("256x256 rgba8+zstd", 256, 256, "0-1", "rgba8", "zstd", "png", [], False),
]


def netns_exec(host, argv):
    return [os.environ["NETNS_SCRIPT"], "exec", host, *[str(a) for a in argv]]


def machine_cpu():
    """(busy, total, steal) jiffies of all CPUs from /proc/stat. Steal is time the hypervisor
    gave this machine's virtual CPUs to others (it counts as busy)."""
    with open("/proc/stat", encoding="ascii") as f:
        values = [int(v) for v in f.readline().split()[1:]]
    idle = values[3] + (values[4] if len(values) > 4 else 0)
    steal = values[7] if len(values) > 7 else 0
    return sum(values) - idle, sum(values), steal


class NetnsCase(ct.Case):
    """A cluster_test Case whose master and workers run on the namespace hosts."""

    def __init__(self, args):
        super().__init__(args)
        self.subnet = os.environ["SUBNET"]
        self.token = self.path("token")
        with open(self.token, "w", encoding="utf-8") as f:
            f.write(os.urandom(16).hex() + "\n")
        self.cpu_mark = self.children_cpu_s()

    @staticmethod
    def children_cpu_s():
        r = resource.getrusage(resource.RUSAGE_CHILDREN)
        return r.ru_utime + r.ru_stime

    def cluster(self, tag, scene_args, frames=None, loop_s=None, out_ext=None, master_extra=(), timeout=120):
        """Master on host `master` (${SUBNET}.1, token required), a worker on each host wI; waits
        for all to exit 0. Returns (out folder or None, frame records, summary, Load): the wall
        time, the CPU time of the cluster's processes and how busy the whole machine was."""
        out = self.mkdir(tag) if out_ext else None
        stats = self.path(f"{tag}-stats.json")
        ready = self.path(f"{tag}.ready")
        run = ["--frames", frames] if frames else ["--loop", str(loop_s)]
        if out:
            run += ["--out", os.path.join(out, f"m_####.{out_ext}")]
        started = time.monotonic()
        cpu_before = self.children_cpu_s()
        machine_before = machine_cpu()
        master = self.spawn(f"{tag}-master", netns_exec("master", [
            self.args.master, *scene_args, *run, "--link-mbps", LINK_MBPS, "--min-workers", WORKERS,
            "--listen", f"{self.subnet}.1:0", "--token-file", self.token, "--ready-file", ready,
            "--stats-json", stats, *master_extra]))

        def address():
            try:
                with open(ready, encoding="utf-8") as f:
                    text = f.read()
            except FileNotFoundError:
                return None
            return text.strip() if text.endswith("\n") else None

        addr = ct.wait_for(address, 30, f"{tag}: the master to listen", [master])
        if not addr.startswith(f"{self.subnet}.1:"):
            fail(f"{tag}: the master listens on {addr}, not on its host address {self.subnet}.1")
        workers = [self.spawn(f"{tag}-w{i}", netns_exec(f"w{i}", [
            self.args.worker, "--connect", addr, "--token-file", self.token, "--threads", 1,
            "--name", f"host-w{i}", "--retry-seconds", 20])) for i in range(1, WORKERS + 1)]
        ct.expect_exit(master, 0, timeout, "render every frame and exit")
        for w in workers:
            ct.expect_exit(w, 0, 15, "exit 0 after the master's Goodbye")
        machine_after = machine_cpu()
        total = max(1, machine_after[1] - machine_before[1])
        load = Load(time.monotonic() - started, self.children_cpu_s() - cpu_before,
                    (machine_after[0] - machine_before[0]) / total, (machine_after[2] - machine_before[2]) / total)
        records, summary = ct.read_stats(stats)
        if summary is None or not records:
            fail(f"{tag}: no frames or no summary in {stats}")
        joined = ct.worker_labels(master)
        if sorted(joined) != [f"host-w{i}" for i in range(1, WORKERS + 1)]:
            fail(f"{tag}: the master saw workers {sorted(joined)}, expected host-w1..host-w{WORKERS}")
        for name in joined:
            peer = re.search(rf"\({re.escape(name)} at ([0-9.]+):", master.log())
            want = f"{self.subnet}.{10 + int(name[len('host-w'):])}"
            if not peer or peer.group(1) != want:
                fail(f"{tag}: {name} connected from {peer and peer.group(1)}, not from its host {want}")
        return out, records, summary, load


class Load:
    def __init__(self, wall_s, cpu_s, machine_busy, steal):
        self.wall_s, self.cpu_s, self.machine_busy, self.steal = wall_s, cpu_s, machine_busy, steal

    def __str__(self):
        return (f"cluster CPU {self.cpu_s / self.wall_s:.2f} cores, machine {100 * self.machine_busy:.0f}% busy "
                f"({100 * self.steal:.0f}% stolen by the hypervisor) over {self.wall_s:.1f} s")


def rates(records, summary):
    """(measured fps, bound fps, bytes per frame). Measured: frames per second of the master's
    frame intervals without the first frame, whose interval is its own wall time (from its
    opening, the probe and the pipeline's start included) rather than a time between frames.
    With frames in flight a single interval can be shorter than a frame's link time; their sum
    cannot."""
    ordered = sorted(records, key=lambda r: r["sequence"])
    steady = ordered[1:] or ordered
    measured = 1000.0 * len(steady) / sum(r["interval_ms"] for r in steady)
    return measured, summary["median_bound_fps"], summary["median_bytes_per_frame"]


def describe_frames(records):
    return ", ".join(f"{r['fps']:.2f}" for r in sorted(records, key=lambda r: r["sequence"]))


def case_check(c):
    for label, width, height, frames, wire, comp, ext, extra, bound_check in CHECKS:
        tag = re.sub(r"[^a-z0-9]+", "-", label)
        scene = ["--width", width, "--height", height]
        first, last = (int(x) for x in frames.split("-"))
        ref = c.reference(f"{tag}-ref", scene, frames, ext, extra)
        # A busy machine can starve the cluster of CPU for a while: up to ATTEMPTS runs, each reported.
        for attempt in range(1, ATTEMPTS + 1):
            run_tag = f"{tag}-{attempt}"
            out, records, summary, load = c.cluster(
                run_tag, scene, frames=frames, out_ext=ext, master_extra=["--wire", wire, "--compress", comp, *extra])
            if sorted(r["frame"] for r in records) != list(range(first, last + 1)):
                fail(f"{label}: stats hold frames {[r['frame'] for r in records]}, expected {frames}")
            c.expect_frames_equal(out, "m", ref, range(first, last + 1), ext)
            measured, bound, frame_bytes = rates(records, summary)
            if summary.get("link_source") != "given" or not bound:
                fail(f"{label}: the master logged no bound from --link-mbps: {summary}")
            if not bound_check:
                print(f"{label}: frames {frames} equal rtc-render's; {frame_bytes / 1e6:.3f} MB/frame "
                      f"(compression {summary['compression_ratio']:.2f}:1); frame rate not checked (CPU-bound)")
                break
            ratio = measured / bound
            print(f"{label} (run {attempt}): frames {frames} equal rtc-render's; {frame_bytes / 1e6:.2f} MB/frame; "
                  f"master's bound {bound:.3f} fps ({summary['link_mbit_per_s']:.1f} Mbit/s of messages on "
                  f"{LINK_MBPS} Mbit/s), measured {measured:.3f} fps (per frame: {describe_frames(records)}), "
                  f"measured/bound {ratio:.3f}; {load}", flush=True)
            if abs(ratio - 1) <= TOLERANCE:
                break
            why = (f"{label}: measured {measured:.3f} fps is {100 * (ratio - 1):+.1f}% off the master's link bound "
                   f"{bound:.3f} fps (allowed {100 * TOLERANCE:.0f}%); per-frame fps {describe_frames(records)}; {load}")
            if attempt == ATTEMPTS:
                fail(why + ("; the machine's CPUs were saturated, so the run was CPU-bound rather than link-bound"
                            if load.machine_busy > 0.9 else ""))
            print(f"again: {why}")


def iperf_goodput_mbit(c):
    """TCP goodput w1 -> master in Mbit/s, measured by iperf3 for 4 s with the first second left
    out; None without iperf3. One stream fills the master's link (the same switch port all tiles
    cross); three started one after another do not add up to a clean figure, since each ramps up
    behind the others' queue."""
    if shutil.which("iperf3") is None:
        return None
    server = c.spawn("iperf3-server", netns_exec("master", ["iperf3", "-s", "-1", "-p", "5201"]))
    time.sleep(0.5)
    client = c.spawn("iperf3-w1", netns_exec("w1", ["iperf3", "-c", f"{c.subnet}.1", "-p", "5201", "-t", 4, "-O", 1,
                                                   "-J"]))
    ct.expect_exit(client, 0, 30, "measure the link with iperf3")
    server.wait(10, "iperf3 server to finish")
    try:
        return json.loads(client.log())["end"]["sum_received"]["bits_per_second"] / 1e6
    except (ValueError, KeyError) as e:
        fail(f"cannot read iperf3's JSON ({e}): {client.log()[:500]}")


def case_table(c):
    goodput_before = iperf_goodput_mbit(c)
    print(f"link goodput w1 -> master (iperf3, 1 TCP stream, 4 s): {goodput_before} Mbit/s")
    rows = []
    message_mbit = 0.0
    for size in c.args.sizes:
        for wire in ("rgba8", "half", "float"):
            for comp in ("none", "lz4", "zstd"):
                tag = f"{size}-{wire}-{comp}"
                _, records, summary, load = c.cluster(
                    tag, ["--width", size, "--height", size], frames=f"0-{c.args.frames - 1}",
                    master_extra=["--wire", wire, "--compress", comp, *ct.WHOLE], timeout=300)
                measured, bound, frame_bytes = rates(records, summary)
                message_mbit = summary["link_mbit_per_s"]
                achieved_mbit = measured * frame_bytes * 8 / 1e6
                ratio = measured / bound if bound else 0
                # Within 10% of the bound: the link is the limit; else the 2 shared cores are.
                limit = "link" if ratio >= 1 - TOLERANCE else "CPU"
                rows.append((size, wire, comp, frame_bytes / 1e6, summary["compression_ratio"], bound, measured,
                             ratio, achieved_mbit, load, limit))
                print(f"{tag}: {measured:.2f} fps of a {bound:.2f} fps bound ({ratio:.2f}), {achieved_mbit:.1f} Mbit/s, "
                      f"{load} -> {limit}-bound", flush=True)
    goodput_after = iperf_goodput_mbit(c)
    goodput_text = (f"{goodput_before:.1f} Mbit/s before the runs, {goodput_after:.1f} after" if goodput_before
                    else "n/a (no iperf3)")
    with open(c.args.out, "w", encoding="utf-8") as f:
        f.write("| size | wire | compress | MB/frame | ratio | bound fps | achieved fps | achieved / bound "
                "| messages Mbit/s | cluster CPU (cores) | machine busy | limit |\n")
        f.write("|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---|\n")
        for (size, wire, comp, mb, cr, bound, measured, ratio, mbit, load, limit) in rows:
            f.write(f"| {size}x{size} | {wire} | {comp} | {mb:.3f} | {cr:.2f} | {bound:.2f} | {measured:.2f} | "
                    f"{ratio:.2f} | {mbit:.1f} | {load.cpu_s / load.wall_s:.2f} | {100 * load.machine_busy:.0f}% | "
                    f"{limit} |\n")
        f.write(f"\nEach row: {c.args.frames} frames of the built-in scene, each traced whole (--temporal off), "
                f"discarded (no --out); achieved fps over the frames after the first. Link: {LINK_MBPS} Mbit/s line rate per host; the master's bound counts "
                f"{message_mbit:.1f} Mbit/s of messages into the master; iperf3 TCP goodput w1 -> master: "
                f"{goodput_text}.\n")
    print(f"wrote {c.args.out}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("case", choices=["check", "table"])
    parser.add_argument("--master", required=True)
    parser.add_argument("--worker", required=True)
    parser.add_argument("--render", required=True)
    parser.add_argument("--oiiotool", default="oiiotool")
    parser.add_argument("--keep", action="store_true", help="keep the temporary folder")
    parser.add_argument("--out", default="results-table.md", help="table: Markdown file to write")
    parser.add_argument("--frames", type=int, default=10, help="table: frames per configuration (at least 2)")
    parser.add_argument("--sizes", default="512,1024", help="table: square frame sizes")
    args = parser.parse_args()
    args.sizes = [int(s) for s in args.sizes.split(",")]
    if args.frames < 2:
        parser.error("--frames: at least 2 (the first frame is not counted)")
    for var in ("NETNS_SCRIPT", "PREFIX", "SUBNET"):
        if var not in os.environ:
            print(f"{var} is not set: run this under tests/deploy/netns/with_netns_cluster.sh", file=sys.stderr)
            return 2

    return ct.run_case(f"netns {args.case}", lambda: NetnsCase(args),
                       {"check": case_check, "table": case_table}[args.case])


if __name__ == "__main__":
    sys.exit(main())
