#!/usr/bin/env bash
# Regenerates tests/bench/results/temporal.md: object-space temporal coherence (issue 7) on
# static-camera animations. For each animation, rtc-render traces every frame whole
# (--temporal off) and incrementally (--temporal on), alternating, REPEAT times, on THREADS
# threads; per frame it logs prepare (kd-tree) and render times, the render's process CPU
# time and the tiles retraced. Then a master with 2 local workers renders the animation both
# ways and its stats JSON gives the bytes each frame put on the wire. Figures are medians
# over the runs.
# Usage: [TILE=16] [FIRST=15] tests/bench/run_temporal.sh [THREADS] [REPEAT] [ANIMATION.json ...]
set -euo pipefail
cd "$(dirname "$0")/../.."
threads=${1:-1}
repeat=${2:-3}
# Both modes at the tile size temporal coherence uses by default (kTemporalTileSize), so full
# and incremental frames cut the image alike; TILE=32 gives the other default.
tile=${TILE:-16}
first=${FIRST:-15}
# "A-B" of an animation's first two frames (temporal coherence needs more than one frame).
first_two() {
  if [ "$1" = default ]; then echo 0-1; else
    python3 -c 'import json,sys; a=json.load(open(sys.argv[1])).get("animation",{}).get("frames",[0]); print(f"{a[0]}-{a[0]+1}")' "$1"
  fi
}
shift $(( $# > 2 ? 2 : $# ))
anims=("$@")
if [ ${#anims[@]} -eq 0 ]; then
  anims=(tests/bench/scenes/office_mover.json tests/bench/scenes/office_mover_desk.json
         tests/bench/scenes/office_mover_mirror.json default tests/temporal/scenes/*.json)
fi
render=build/release/worker/rtc-render
master=build/release/master/rtc-master
worker=build/release/worker/rtc-worker
for b in "$render" "$master" "$worker"; do
  [ -x "$b" ] || { cmake --preset release >/dev/null && cmake --build --preset release --target rtc-render rtc-master rtc-worker; break; }
done
out=tests/bench/results
mkdir -p "$out"
tmp=$(mktemp -d)
pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; rm -rf "$tmp"; }
trap cleanup EXIT
jsonl=$out/temporal.jsonl
: > "$jsonl.tmp"
for anim in "${anims[@]}"; do
  scene=()
  [ "$anim" != default ] && scene=("$anim")
  name=$(basename "$anim" .json)
  for r in $(seq 1 "$repeat"); do
    for mode in off on; do
      echo "rtc-render $name --temporal $mode --threads $threads (run $r of $repeat)" >&2
      "$render" "${scene[@]}" --temporal "$mode" --tile "$tile" --threads "$threads" --out "$tmp/f_####.png" --log-level warn \
        | python3 tests/bench/summarize_temporal.py --parse "$name" "$mode" "$r" >> "$jsonl.tmp"
    done
  done
  # The first frame alone, FIRST times each way, alternating (one sample per run above is
  # too few for a ratio of two single frames on a shared machine).
  for r in $(seq 1 "$first"); do
    for mode in off on; do
      "$render" "${scene[@]}" --temporal "$mode" --tile "$tile" --threads "$threads" --frames "$(first_two "$anim")" \
        --out "$tmp/g_####.png" --log-level warn \
        | python3 tests/bench/summarize_temporal.py --parse "$name" "first-$mode" "$r" >> "$jsonl.tmp"
    done
  done
  for mode in off on; do
    echo "cluster $name --temporal $mode (2 workers)" >&2
    rm -f "$tmp/ready" "$tmp/stats.jsonl"
    "$master" "${scene[@]}" --listen 127.0.0.1:0 --ready-file "$tmp/ready" --temporal "$mode" --tile "$tile" --min-workers 2 \
      --stats-json "$tmp/stats.jsonl" --log-level warn &
    m=$!
    pids+=("$m")
    for _ in $(seq 100); do [ -s "$tmp/ready" ] && break; sleep 0.1; done
    for w in 1 2; do
      "$worker" --connect "$(cat "$tmp/ready")" --threads 1 --log-level warn &
      pids+=("$!")
    done
    wait "$m"
    wait
    pids=()
    python3 tests/bench/summarize_temporal.py --cluster "$name" "$mode" "$tmp/stats.jsonl" >> "$jsonl.tmp"
  done
done
mv "$jsonl.tmp" "$jsonl"
python3 tests/bench/summarize_temporal.py --table "$jsonl" > "$out/temporal.md"
echo "wrote $jsonl and $out/temporal.md" >&2
