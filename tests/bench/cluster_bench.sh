#!/usr/bin/env bash
# Cluster benchmarks for the closing notes (figures, not timed tests):
#   scaling  frame rate of rtc-master + W local workers (1 thread each; W = 1, 2, 4) against
#            rtc-render with the same number of threads, on static scenes: the cluster's overhead.
#   link     two network namespaces joined by a veth pair capped with tc tbf (default 100mbit,
#            both ways): the master in one, the workers in the other; for each scene, size,
#            wire format and compression, the logged link bound and the achieved frame rate.
#   tiles    the master's cost per byte by tile size: the embedded scene at SIZE x SIZE (default
#            2048) in float tiles without reflections, 20 frames, one 2-thread worker on loopback;
#            per tile size and compression, the frame rate and the master's network-thread CPU
#            time a frame (RTC_BUILD_DIR=another build's folder compares two builds).
#   write    the master writing its frames: the embedded scene at SIZE x SIZE (default 2048) in
#            512-pixel float tiles without reflections, 16 frames, 8 in flight, one 2-thread
#            worker on loopback, written as EXR float with depth and normals, EXR half and PNG;
#            per format the whole run's time and the master's CPU time a frame (RTC_BUILD_DIR as
#            for tiles).
# Usage (root for `link`):
#   tests/bench/cluster_bench.sh scaling [SECONDS] [SCENE...]
#   tests/bench/cluster_bench.sh link [SECONDS] [SCENE...]      (RATE=100mbit WORKERS=2 SIZES="512 1024"
#                                                                MEASURED_ONLY=1)
#   tests/bench/cluster_bench.sh tiles                          (SIZE=2048 TILES="32 64 256 1024"
#                                                                COMPRESS="none lz4" OUT=cluster_tiles)
#   tests/bench/cluster_bench.sh write                          (SIZE=2048 OUT=cluster_write)
# Writes JSON lines to tests/bench/results/cluster_<mode>.jsonl and a table to cluster_<mode>.md,
# both replaced only when every run succeeded.
# Every frame is traced whole (--temporal off on both programs): with temporal coherence, on by
# default for a still camera, a static scene's frames after the first trace nothing and send no
# pixels, which would measure neither the cluster's overhead nor the link.
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
build="${RTC_BUILD_DIR:-$root/build/release}"
master="$build/master/rtc-master"
worker="$build/worker/rtc-worker"
render="$build/worker/rtc-render"
mode="${1:?usage: cluster_bench.sh scaling|link [SECONDS] [SCENE...]}"
shift
seconds="${1:-8}"
[ $# -gt 0 ] && shift
scenes=("$@")
shared="${RTC_SHARED_SCENES:-$root/../shared/scenes}"
if [ ${#scenes[@]} -eq 0 ]; then
  scenes=("$shared/gltf-samples/view-BoxTextured.json" "$shared/spd-tetra/view.json" "$shared/radiance-office/view.json")
fi
for s in "${scenes[@]}"; do [ -f "$s" ] || { echo "cluster_bench: scene $s not found" >&2; exit 1; }; done
needed=("$master" "$worker")
[ "$mode" = scaling ] && needed+=("$render")
for b in "${needed[@]}"; do [ -x "$b" ] || { echo "cluster_bench: build $b first" >&2; exit 1; }; done
results="$root/tests/bench/results"
mkdir -p "$results"
work="$(mktemp -d "${TMPDIR:-/tmp}/rtc-cluster-bench.XXXXXX")"
pids=()
ns_master="rtcb-m"
ns_workers="rtcb-w"

cleanup() {
  for pid in "${pids[@]}"; do kill -KILL "$pid" 2>/dev/null || true; wait "$pid" 2>/dev/null || true; done
  if [ "$mode" = link ]; then
    ip netns del "$ns_master" 2>/dev/null || true
    ip netns del "$ns_workers" 2>/dev/null || true
  fi
  rm -rf "$work"
}
trap cleanup EXIT

# run_cluster OUT_JSONL NS_MASTER NS_WORKER LISTEN CONNECT WORKERS THREADS MASTER_ARGS...
run_cluster() {
  local out="$1" nsm="$2" nsw="$3" listen="$4" connect="$5" n="$6" threads="$7"
  shift 7
  local pre_m=() pre_w=()
  [ -n "$nsm" ] && pre_m=(ip netns exec "$nsm")
  [ -n "$nsw" ] && pre_w=(ip netns exec "$nsw")
  rm -f "$work/ready" "$work/stats.jsonl"
  "${pre_m[@]}" "$master" --listen "$listen" --ready-file "$work/ready" --min-workers "$n" \
    --stats-json "$work/stats.jsonl" --log-level warn --temporal off "$@" > "$work/master.log" 2>&1 &
  local mpid=$!
  pids=("$mpid")
  for _ in $(seq 1 300); do [ -s "$work/ready" ] && break; sleep 0.1; done
  [ -s "$work/ready" ] || { cat "$work/master.log" >&2; echo "cluster_bench: master did not start" >&2; return 1; }
  local port
  port="$(sed 's/.*://' "$work/ready")"
  for i in $(seq 1 "$n"); do
    "${pre_w[@]}" "$worker" --connect "$connect:$port" --threads "$threads" --name "bench-$i" --log-level warn \
      --retry-seconds 10 "${token_args[@]}" > "$work/worker-$i.log" 2>&1 &
    pids+=($!)
  done
  local status=0 deadline=$(( SECONDS + ${seconds%.*} * 4 + 120 ))
  while kill -0 "$mpid" 2>/dev/null; do
    if [ "$SECONDS" -ge "$deadline" ]; then
      echo "cluster_bench: master still running after its deadline: stopping it" >&2
      kill -TERM "$mpid" 2>/dev/null || true
      sleep 5
      kill -KILL "$mpid" 2>/dev/null || true
    fi
    sleep 0.2
  done
  wait "$mpid" || status=$?
  for pid in "${pids[@]:1}"; do wait "$pid" 2>/dev/null || true; done
  pids=()
  if [ "$status" -ne 0 ] || ! grep -q '"type":"summary"' "$work/stats.jsonl"; then
    cat "$work/master.log" >&2
    echo "cluster_bench: run failed (status $status)" >&2
    return 1
  fi
  grep '"type":"summary"' "$work/stats.jsonl" >> "$out"
}

token_args=()
case "$mode" in
  scaling)
    final="$results/cluster_scaling.jsonl"
    out="$work/cluster_scaling.jsonl"
    : > "$out"
    for scene in "${scenes[@]}"; do
      name="$(basename "$(dirname "$scene")")/$(basename "$scene")"
      for t in 1 2 4; do
        # rtc-render: the same frame 20 times with t threads; its own per-frame render time.
        rm -f "$work"/r_*.png
        "$render" "$scene" --width 512 --height 512 --frames 0-19 --threads "$t" --out "$work/r_####.png" \
          --temporal off --log-level warn > "$work/render.log"
        python3 - "$work/render.log" "$name" "$t" >> "$out" <<'PY'
import json, re, statistics, sys
ms = [float(m.group(1)) for m in re.finditer(r"in ([0-9.]+) s:", open(sys.argv[1]).read())]
render = [float(m.group(1)) for m in re.finditer(r"render ([0-9.]+) ms", open(sys.argv[1]).read())]
if not ms or not render or statistics.median(render) <= 0 or statistics.median(ms) <= 0:
    sys.exit(f"cluster_bench: rtc-render's log has no usable frame times ({sys.argv[1]})")
print(json.dumps({"type": "render", "scene": sys.argv[2], "threads": int(sys.argv[3]),
                  "median_fps_with_write": 1.0 / statistics.median(ms),
                  "median_fps_render_only": 1000.0 / statistics.median(render)}))
PY
        echo "{\"type\":\"cluster\",\"scene\":\"$name\",\"workers\":$t}" >> "$out"
        run_cluster "$out" "" "" 127.0.0.1:0 127.0.0.1 "$t" 1 "$scene" --width 512 --height 512 --loop "$seconds"
        echo "scaling: $name, $t threads / workers done"
      done
    done
    ;;
  link)
    [ "$(id -u)" -eq 0 ] || { echo "cluster_bench link: needs root (network namespaces)" >&2; exit 1; }
    rate="${RATE:-100mbit}"
    nworkers="${WORKERS:-2}"
    sizes="${SIZES:-512 1024}"
    ip netns del "$ns_master" 2>/dev/null || true
    ip netns del "$ns_workers" 2>/dev/null || true
    ip netns add "$ns_master"
    ip netns add "$ns_workers"
    ip link add rtcb-a type veth peer name rtcb-b
    ip link set rtcb-a netns "$ns_master"
    ip link set rtcb-b netns "$ns_workers"
    ip -n "$ns_master" addr add 10.78.0.1/24 dev rtcb-a
    ip -n "$ns_workers" addr add 10.78.0.2/24 dev rtcb-b
    for ns in "$ns_master" "$ns_workers"; do ip -n "$ns" link set lo up; done
    ip -n "$ns_master" link set rtcb-a up
    ip -n "$ns_workers" link set rtcb-b up
    ip netns exec "$ns_master" tc qdisc add dev rtcb-a root tbf rate "$rate" burst 32kbit latency 400ms overhead 24
    ip netns exec "$ns_workers" tc qdisc add dev rtcb-b root tbf rate "$rate" burst 32kbit latency 400ms overhead 24
    head -c 32 /dev/urandom | od -An -tx1 | tr -d ' \n' > "$work/token"
    token_args=(--token-file "$work/token")
    final="$results/cluster_link.jsonl"
    # MEASURED_ONLY=1: only the runs where the master measures the link itself.
    [ "${MEASURED_ONLY:-0}" = 1 ] && { final="$results/cluster_link_measured.jsonl"; sizes=""; }
    out="$work/$(basename "$final")"
    : > "$out"
    mbps="$(python3 -c "import re,sys; r=sys.argv[1].lower(); m=re.match(r'([0-9.]+)(k|m|g)bit',r); print(float(m.group(1))*{'k':1e-3,'m':1,'g':1e3}[m.group(2)])" "$rate")"
    for scene in "${scenes[@]}"; do
      name="$(basename "$(dirname "$scene")")/$(basename "$scene")"
      for size in $sizes; do
        for wire in rgba8 half float; do
          for comp in none lz4 zstd; do
            echo "{\"type\":\"case\",\"scene\":\"$name\",\"size\":$size,\"wire\":\"$wire\",\"compress\":\"$comp\",\"rate\":\"$rate\"}" >> "$out"
            run_cluster "$out" "$ns_master" "$ns_workers" 10.78.0.1:0 10.78.0.1 "$nworkers" 1 "$scene" \
              --width "$size" --height "$size" --loop "$seconds" --wire "$wire" --compress "$comp" \
              --link-mbps "$mbps" "${token_args[@]}"
            echo "link: $name ${size}x$size $wire+$comp done"
          done
        done
      done
      # The same link measured by the master instead of given (rgba8, no compression).
      echo "{\"type\":\"case\",\"scene\":\"$name\",\"size\":512,\"wire\":\"rgba8\",\"compress\":\"none\",\"rate\":\"$rate\",\"measured\":true}" >> "$out"
      run_cluster "$out" "$ns_master" "$ns_workers" 10.78.0.1:0 10.78.0.1 "$nworkers" 1 "$scene" \
        --width 512 --height 512 --loop "$seconds" "${token_args[@]}"
    done
    ;;
  tiles)
    size="${SIZE:-2048}"
    final="$results/${OUT:-cluster_tiles}.jsonl"
    out="$work/$(basename "$final")"
    : > "$out"
    for comp in ${COMPRESS:-none lz4}; do
      for tile in ${TILES:-32 64 256 1024}; do
        echo "{\"type\":\"tiles\",\"size\":$size,\"tile\":$tile,\"wire\":\"float\",\"compress\":\"$comp\"}" >> "$out"
        run_cluster "$out" "" "" 127.0.0.1:0 127.0.0.1 1 2 --width "$size" --height "$size" --tile "$tile" \
          --max-depth 0 --frames 0-19 --wire float --compress "$comp" --link-mbps 1000
        echo "tiles: ${size}x$size, $tile-pixel tiles, float+$comp done"
      done
    done
    ;;
  write)
    size="${SIZE:-2048}"
    final="$results/${OUT:-cluster_write}.jsonl"
    out="$work/$(basename "$final")"
    : > "$out"
    for format in exr-float exr-half png; do
      args=(--out "$work/frames/f_####.${format%%-*}")
      [ "$format" = exr-float ] && args+=(--exr-float)
      rm -rf "$work/frames"
      mkdir -p "$work/frames"
      echo "{\"type\":\"write\",\"size\":$size,\"tile\":512,\"in_flight\":8,\"format\":\"$format\"}" >> "$out"
      run_cluster "$out" "" "" 127.0.0.1:0 127.0.0.1 1 2 --width "$size" --height "$size" --tile 512 \
        --max-depth 0 --frames 0-15 --frames-in-flight 8 --tiles-per-worker 128 --wire float --compress none \
        --link-mbps 1000 "${args[@]}"
      written="$(find "$work/frames" -name 'f_*' | wc -l)"
      [ "$written" -eq 16 ] || { echo "cluster_bench: $format: $written frames written, not 16" >&2; exit 1; }
      echo "write: ${size}x$size, $format done"
    done
    ;;
  *) echo "cluster_bench: unknown mode $mode (scaling, link, tiles or write)" >&2; exit 2 ;;
esac
python3 "$root/tests/bench/cluster_summary.py" "$out" > "$work/summary.md"
mv "$out" "$final"
mv "$work/summary.md" "${final%.jsonl}.md"
cat "${final%.jsonl}.md"
