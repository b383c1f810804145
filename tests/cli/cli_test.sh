#!/usr/bin/env bash
# Command-line checks: runs rtc-render and rtc-bench as a user would and asserts exit statuses,
# messages and the files written. One case per ctest entry (tests/cli/CMakeLists.txt).
#
# usage: cli_test.sh CASE RTC_RENDER [RTC_BENCH]
set -u -o pipefail

if [[ $# -lt 2 ]]; then
  echo "usage: $0 CASE RTC_RENDER [RTC_BENCH]" >&2
  exit 2
fi
readonly test_case=$1
readonly render=$2
readonly bench=${3:-}

work=$(mktemp -d "${TMPDIR:-/tmp}/rtc-cli-${test_case}.XXXXXX") || exit 2
readonly work
trap 'rm -rf "$work"' EXIT

fail() {
  echo "FAIL [$test_case]: $*" >&2
  exit 1
}

# run NAME CMD...: runs CMD with stdout/stderr in $work/NAME.out / NAME.err; status in $rc.
rc=0
run() {
  local name=$1
  shift
  "$@" >"$work/$name.out" 2>"$work/$name.err"
  rc=$?
}

show() {
  local name=$1
  echo "--- stdout of $name:"
  cat "$work/$name.out"
  echo "--- stderr of $name:"
  cat "$work/$name.err"
}

expect_rc() {
  local name=$1 want=$2
  if [[ $rc -ne $want ]]; then
    show "$name" >&2
    if [[ $rc -gt 128 ]]; then
      fail "$name: exit status $rc (killed by signal $((rc - 128))), expected $want"
    fi
    fail "$name: exit status $rc, expected $want"
  fi
}

# expect_in NAME out|err TEXT: the stream holds TEXT (fixed string).
expect_in() {
  local name=$1 stream=$2 text=$3
  if ! grep -qF -- "$text" "$work/$name.$stream"; then
    show "$name" >&2
    fail "$name: std$stream lacks \"$text\""
  fi
}

# expect_failure STATUS NAME TEXT... -- CMD...: CMD exits with STATUS (not a signal, not an
# abort), prints one "PROGRAM: error: ..." line on stderr holding every TEXT, and nothing on
# stdout.
expect_failure() {
  local status=$1 name=$2
  shift 2
  local texts=()
  while [[ $1 != "--" ]]; do
    texts+=("$1")
    shift
  done
  shift
  run "$name" "$@"
  expect_rc "$name" "$status"
  local program line text
  program=$(basename "$1")
  if [[ $(grep -cF -- "$program: error: " "$work/$name.err") -ne 1 ]]; then
    show "$name" >&2
    fail "$name: expected one \"$program: error: ...\" line on stderr"
  fi
  line=$(grep -F -- "$program: error: " "$work/$name.err")
  for text in "${texts[@]}"; do
    if [[ $line != *"$text"* ]]; then
      show "$name" >&2
      fail "$name: the error line lacks \"$text\""
    fi
  done
  for text in "internal check failed" "terminate called" "Sanitizer" "core dumped"; do
    if grep -qF -- "$text" "$work/$name.err"; then
      show "$name" >&2
      fail "$name: stderr shows a crash (\"$text\")"
    fi
  done
  if [[ -s $work/$name.out ]]; then
    show "$name" >&2
    fail "$name: a failed run printed a summary on stdout"
  fi
}

# expect_error NAME TEXT... -- CMD...: bad input, exit status 1 (expect_failure).
expect_error() { expect_failure 1 "$@"; }

# expect_usage_error NAME TEXT... -- CMD...: a command line CMD cannot take: exit status 2, and
# the error line is followed by the pointer to --help.
expect_usage_error() {
  expect_failure 2 "$@"
  local name=$1 program
  while [[ $1 != "--" ]]; do shift; done
  program=$(basename "$2")
  expect_in "$name" err "run '$program --help' for the options"
}

# A tiny scene of its own (no dependence on ../shared/scenes): a floor given as one quad
# (fanned: triangles 0, 1), a degenerate face (2, dropped by the loader but still counted in
# the ids), a tetrahedron (3-6) and a pentagon standing behind it (7-9). Faces are listed in
# the OBJ in this order, so these are the ids rtc-bench --dump reports.
write_small_scene() {
  cat >"$work/tiny.obj" <<'EOF'
# rtc CLI test scene
v -2 0 -2
v 2 0 -2
v 2 0 2
v -2 0 2
v -0.6 0.1 0.4
v 0.6 0.1 0.5
v 0.1 0.2 -0.6
v 0.05 1.1 0.1
v -1.5 0.2 -1.2
v -0.5 0.3 -1.3
v -0.3 1.0 -1.3
v -1.0 1.5 -1.2
v -1.7 0.9 -1.2
f 1 4 3 2
f 1 1 2
f 5 6 8
f 6 7 8
f 7 5 8
f 5 7 6
f 9 10 11 12 13
EOF
  cat >"$work/view.json" <<'EOF'
{
  "name": "tiny_cli",
  "mesh": "tiny.obj",
  "camera": {"eye": [0.3, 1.5, 5.0], "look_at": [0.0, 0.3, 0.0], "up": [0, 1, 0], "vfov_deg": 40},
  "lights": [{"position": [3, 5, 4], "color": [1, 1, 1]}],
  "resolution": [40, 30]
}
EOF
}

# expect_only_image PATH: PATH is the one file in $work besides the logs of run(): the
# temporary file it was written to (.NAME.tmp-PID-...) was renamed, not left behind.
expect_only_image() {
  local files
  files=$(find "$work" -mindepth 1 -maxdepth 1 ! -name '*.out' ! -name '*.err')
  [[ $files == "$1" ]] || { ls -la "$work" >&2; fail "expected only $1 in $work"; }
}

case_render_png() {
  local out="$work/f.png"
  run render "$render" --frames 0 --width 64 --height 48 --out "$out"
  expect_rc render 0
  expect_in render out "frame 0: wrote $out (64x48)"
  [[ $(grep -c '^frame ' "$work/render.out") -eq 1 ]] || { show render >&2; fail "expected one summary line"; }
  [[ -f $out ]] || fail "$out was not written"
  run info oiiotool --info "$out"
  expect_rc info 0
  expect_in info out "64 x   48, 4 channel, uint8 png"
  expect_only_image "$out"
}

case_render_exr() {
  local out="$work/f.exr"
  run render "$render" --frames 0 --width 64 --height 48 --out "$out"
  expect_rc render 0
  expect_in render out "frame 0: wrote $out (64x48)"
  run info oiiotool --info -v "$out"
  expect_rc info 0
  expect_in info out "64 x   48, 8 channel"
  expect_in info out "channel list: R (half), G (half), B (half), A (half), Z (float), N.X (half), N.Y (half), N.Z (half)"
  expect_only_image "$out"
  run render_float "$render" --frames 0 --width 64 --height 48 --exr-float --out "$work/g.exr"
  expect_rc render_float 0
  run info_float oiiotool --info -v "$work/g.exr"
  # oiiotool lists the types per channel only when they differ.
  expect_in info_float out "64 x   48, 8 channel, float openexr"
  expect_in info_float out "channel list: R, G, B, A, Z, N.X, N.Y, N.Z"
}

case_missing_scene() {
  expect_error missing "$work/no_such_scene.json" "cannot open" -- \
    "$render" "$work/no_such_scene.json" --frames 0 --width 8 --height 8 --out "$work/o.png"
  [[ ! -e $work/o.png ]] || fail "an image was written for a missing scene"
}

case_unknown_json_field() {
  printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n' >"$work/tri.obj"
  cat >"$work/scene.json" <<'EOF'
{"mesh": "tri.obj", "lights": [{"position": [0, 0, 5], "colour": [1, 1, 1]}]}
EOF
  expect_error unknown "$work/scene.json" 'unknown field "lights[0].colour"' -- \
    "$render" "$work/scene.json" --frames 0 --width 8 --height 8 --out "$work/o.png"
  printf '{"mesh": "tri.obj", "resolution": [8, 8], "shutter": 1}\n' >"$work/top.json"
  expect_error unknown_top "$work/top.json" 'unknown field "shutter"' -- \
    "$render" "$work/top.json" --frames 0 --out "$work/o.png"
  [[ ! -e $work/o.png ]] || fail "an image was written for a bad scene"
}

case_obj_index_out_of_range() {
  printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\n# the next face is fine, the one after it is not\nf 1 2 3\nf 1 2 7\n' \
    >"$work/bad.obj"
  expect_error obj "$work/bad.obj:6:" "index 7" "out of range" -- \
    "$render" "$work/bad.obj" --frames 0 --width 8 --height 8 --out "$work/o.png"
}

case_truncated_ply() {
  python3 - "$work/trunc.ply" <<'EOF' || fail "could not write the PLY"
import struct, sys
header = (b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n"
          b"property float x\nproperty float y\nproperty float z\n"
          b"element face 1\nproperty list uchar int vertex_indices\nend_header\n")
body = struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0) + struct.pack("<B3i", 3, 0, 1, 2)
# Cut inside the second vertex.
open(sys.argv[1], "wb").write(header + body[:20])
EOF
  expect_error ply "$work/trunc.ply" "truncated" -- \
    "$render" "$work/trunc.ply" --frames 0 --width 8 --height 8 --out "$work/o.png"
}

case_empty_frame_range() {
  expect_error frames "--frames" "5-2" "empty range" -- \
    "$render" --frames 5-2 --width 8 --height 8 --out "$work/o_####.png"
  [[ -z $(find "$work" -name 'o_*') ]] || fail "frames were written for an empty range"
}

case_exr_compression() {
  # A word --exr-compression does not know is refused before anything is rendered; a lossy one
  # is warned about; piz writes a file whose header names it.
  expect_error exr_bad "--exr-compression: expected none, rle, zips, zip, piz, pxr24, b44, b44a, dwaa or dwab" '"zip9"' -- \
    "$render" --frames 0 --width 8 --height 8 --exr-compression zip9 --out "$work/c.exr"
  [[ ! -e $work/c.exr ]] || fail "a frame was written with a bad --exr-compression"
  run exr_dwaa "$render" --frames 0 --width 16 --height 12 --exr-compression dwaa --out "$work/d.exr"
  expect_rc exr_dwaa 0
  expect_in exr_dwaa err "--exr-compression dwaa is lossy"
  # b44 keeps float channels: no warning with --exr-float.
  run exr_b44 "$render" --frames 0 --width 16 --height 12 --exr-compression b44 --exr-float --out "$work/b.exr"
  expect_rc exr_b44 0
  run exr_piz "$render" --frames 0 --width 16 --height 12 --exr-compression piz --out "$work/p.exr"
  expect_rc exr_piz 0
  for name in exr_piz exr_b44; do
    if grep -q "lossy" "$work/$name.err"; then show $name >&2; fail "$name: called lossy"; fi
  done
  run info_piz oiiotool --info -v "$work/p.exr"
  expect_rc info_piz 0
  expect_in info_piz out 'compression: "piz"'
}

case_missing_out_folder() {
  expect_error out_folder "$work/missing/f.png" "$work/missing" "does not exist" -- \
    "$render" --frames 0 --width 16 --height 16 --out "$work/missing/f.png"
  [[ ! -e $work/missing ]] || fail "the missing folder was created"
}

case_bad_output_checked_first() {
  # Checked before any frame is rendered: no image appears.
  expect_error out_ext "--out" "o_0000.xyz" "unsupported extension '.xyz'" -- \
    "$render" --frames 0-1 --width 16 --height 16 --out "$work/o_####.xyz"
  mkdir "$work/taken.png"
  expect_error out_is_folder "--out" "$work/taken.png" "is a folder" -- \
    "$render" --frames 0 --width 16 --height 16 --out "$work/taken.png"
  # Before the scene is loaded (here: before it is found missing).
  expect_error out_before_load "--out" "o.xyz: unsupported extension '.xyz'" -- \
    "$render" "$work/no-such-scene.json" --out "$work/o.xyz"
  expect_error out_folder_before_load "--out" "folder '$work/absent' does not exist" -- \
    "$render" "$work/no-such-scene.json" --out "$work/absent/o_####.png"
  expect_error out_empty "--out: the pattern is empty" -- \
    "$render" --frames 0 --width 16 --height 16 --out ""
  expect_error frames_empty "--frames" 'got ""' -- \
    "$render" --frames "" --width 16 --height 16 --out "$work/o.png"
  expect_error log_level "--log-level" '"loud"' -- \
    "$render" --frames 0 --width 16 --height 16 --log-level loud --out "$work/o.png"
  # What CLI11 itself refuses is a usage error: exit 2, one "rtc-render: error: ..." line naming
  # the option and a pointer to --help (CLI11's own codes were 105-109, with no program name).
  # NaN used to pass the range checks.
  expect_usage_error min_weight_nan "--min-weight" "is not a number" -- \
    "$render" --frames 0 --width 16 --height 16 --min-weight nan --out "$work/o.png"
  expect_usage_error unknown_option "--colour" -- "$render" --frames 0 --colour red --out "$work/o.png"
  expect_usage_error width_range "--width" "not in range 1 to 32768" -- "$render" --width 0 --out "$work/o.png"
  # An empty value is not the option left out (it ran with the best ISA).
  expect_usage_error isa_empty "--isa: the value is empty" -- "$render" --frames 0 --isa "" --out "$work/o.png"
  run help "$render" --help
  expect_rc help 0
  expect_in help out "--min-weight"
  [[ -z $(find "$work" -name 'o_*' -o -name 'o.png') ]] || fail "an image was written despite a bad option"
}

case_frame_too_big_for_memory() {
  # 32768x32768 EXR with depth and normals holds 34.4 GB, and writing it takes 1.07 GB more:
  # refused up front where that is more than the machine has (the test machines have 24 GB),
  # instead of being killed for memory later.
  local avail_kb
  avail_kb=$(awk '/^MemAvailable:/ {print $2}' /proc/meminfo)
  if [[ -z $avail_kb ]] || (( avail_kb * 1024 >= 35433480192 )); then
    echo "skipped: MemAvailable ${avail_kb:-unknown} kB is enough for the frame"
    exit 77
  fi
  expect_error big_frame "a 32768x32768 frame and its writing needs at least 35.4 GB of memory" "--no-depth --no-normal" -- \
    "$render" --frames 0 --width 32768 --height 32768 --out "$work/big.exr"
  [[ ! -e $work/big.exr ]] || fail "an image was written"
}

case_output_checked_for_every_frame() {
  # Frame 1's folder is missing, frame 2's name is a folder: refused before frame 0 is rendered.
  mkdir -p "$work/run_00" "$work/f_0002.png"
  expect_error later_folder "--out" "$work/run_01/f.png" "does not exist" "gives this name for frame 1" -- \
    "$render" --frames 0-1 --width 16 --height 16 --out "$work/run_##/f.png"
  expect_error later_name "--out" "$work/f_0002.png: is a folder (frame 2's name" -- \
    "$render" --frames 0-3 --width 16 --height 16 --out "$work/f_####.png"
  [[ -z $(find "$work" -name '*.png' -type f) ]] || fail "a frame was written before a later frame's name was refused"
  # A JPEG wider than libjpeg takes (65500 pixels): refused before rendering, with the way out
  # (it ended the process from inside libjpeg after the frame was rendered).
  printf 'v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 45\nhither 1\nresolution 16 16\nl 1 1 1\nf 1 1 1 1 0 0 0 1\np 3\n0 0 0\n1 0 0\n0 1 0\n' >"$work/tri.nff"
  printf '{"mesh": "tri.nff", "resolution": [65501, 1], "camera": {"eye": [0, 0, 5], "look_at": [0, 0, 0], "up": [0, 1, 0], "vfov_deg": 45}}\n' >"$work/wide.json"
  expect_error jpeg_wide "--out" "a JPEG file holds at most 65500 pixels a side, and the frame is 65501x1" -- \
    "$render" "$work/wide.json" --out "$work/wide.jpg"
  [[ ! -e $work/wide.jpg ]] || fail "the JPEG was written"
  # No --out: the default folder out/ (here a file) cannot be made.
  touch "$work/out"
  cd "$work" || fail "cannot enter $work"
  run default_out "$render" --frames 0 --width 16 --height 16
  cd - >/dev/null || fail "cannot leave $work"
  expect_rc default_out 1
  expect_in default_out err "cannot make out/, the output folder when no --out is given"
  expect_in default_out err "(give --out)"
  # A report that cannot reach standard output fails the run; the frame is written all the same.
  "$render" --frames 0 --width 16 --height 16 --out "$work/report.png" >/dev/full 2>"$work/dev_full.err"
  rc=$?
  [[ $rc -eq 1 ]] || { cat "$work/dev_full.err" >&2; fail "rtc-render with stdout on /dev/full: exit status $rc, expected 1"; }
  grep -qF "standard output: the frames' report could not be written" "$work/dev_full.err" ||
    { cat "$work/dev_full.err" >&2; fail "rtc-render with stdout on /dev/full: no word of the lost report"; }
  [[ -s $work/report.png ]] || fail "rtc-render with stdout on /dev/full wrote no frame"
}

case_degenerate_camera() {
  # The camera reaches look_at at frame 1 of 3: refused, naming the file and the frame, before
  # frame 0 is written.
  printf 'v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 45\nhither 1\nresolution 16 16\nl 1 1 1\nf 1 1 1 1 0 0 0 1\np 3\n0 0 0\n1 0 0\n0 1 0\n' >"$work/tri.nff"
  cat >"$work/moving.json" <<'JSON'
{"mesh": "tri.nff", "resolution": [16, 16],
 "camera": {"eye": [0, 0, 5], "look_at": [0, 0, 0], "up": [0, 1, 0], "vfov_deg": 45},
 "animation": {"frames": [0, 2], "camera": [
   {"frame": 0, "eye": [0, 0, 5], "look_at": [0, 0, 0]},
   {"frame": 2, "eye": [0, 0, -5], "look_at": [0, 0, 0]}]}}
JSON
  expect_error camera "$work/moving.json" "frame 1" "eye and look_at coincide" -- \
    "$render" "$work/moving.json" --out "$work/m_####.png"
  [[ -z $(find "$work" -name 'm_*') ]] || fail "frames were written for a scene whose camera degenerates at frame 1"
}

case_bench_degenerate_camera() {
  # rtc-bench times the scene's first frame and checks its camera as rtc-render does, naming the
  # file (it used to fail inside the first trace with the camera's message alone).
  [[ -n $bench ]] || fail "no rtc-bench given"
  printf 'v\nfrom 0 0 0\nat 0 0 0\nup 0 1 0\nangle 45\nhither 1\nresolution 16 16\nl 1 1 1\nf 1 1 1 1 0 0 0 1\np 3\n0 0 -5\n1 0 -5\n0 1 -5\n' >"$work/cam.nff"
  expect_error bench "$work/cam.nff" "frame 0" "eye and look_at coincide" -- \
    "$bench" "$work/cam.nff" --mode primary --reps 1 --build-reps 1
}

case_interrupted() {
  # SIGINT at seven moments of a run whose frames take about as long to write as to render
  # (spread over one uninterrupted run's time, so that any machine's speed is covered): a death
  # by SIGINT (130) with a message, every frame file that is there whole (readable, the full
  # size), and no temporary file left (a signal during a write used to leave .f_NNNN.tmp-*).
  local args=(--width 1200 --height 900 --frames 0-5 --temporal off --exr-float)
  # The shorter of two uninterrupted runs: under ctest -j a run slowed by another test's load
  # would put the later signals past the end of runs that go at full speed.
  local t0 t1 total=""
  for _ in 1 2; do
    rm -rf "$work/whole" && mkdir "$work/whole"
    t0=$(date +%s.%N)
    run whole "$render" "${args[@]}" --out "$work/whole/f_####.exr"
    t1=$(date +%s.%N)
    expect_rc whole 0
    total=$(python3 -c "print(min(x for x in ($t1 - $t0, ${total:-1e9})))")
  done
  local k i=0 wrote_through=0 stopped=0 f delay
  for k in 1 2 3 4 5 6 7; do
    i=$((i + 1))
    delay=$(python3 -c "print(round($total * $k / 8, 2))")
    mkdir "$work/i$i"
    # A background job of a script starts with SIGINT ignored (and rtc-render leaves it so): env
    # gives it the default disposition a terminal's foreground job has.
    env --default-signal=INT "$render" "${args[@]}" --out "$work/i$i/f_####.exr" \
      >"$work/int$i.out" 2>"$work/int$i.err" &
    local pid=$!
    sleep "$delay"
    kill -INT "$pid" 2>/dev/null
    wait "$pid"
    rc=$?
    if [[ $rc -eq 0 ]]; then
      # Finished before the signal: then every frame is there and nothing speaks of a stop.
      [[ $(find "$work/i$i" -name 'f_*.exr' | wc -l) -eq 6 ]] || { show "int$i" >&2; fail "exit 0 after SIGINT at $delay s without all 6 frames"; }
      if grep -q "interrupted" "$work/int$i.err"; then show "int$i" >&2; fail "exit 0 after an interruption at $delay s"; fi
    else
      [[ $rc -eq 130 ]] || { show "int$i" >&2; fail "SIGINT after $delay s: exit status $rc, expected 130"; }
      stopped=$((stopped + 1))
      # (A signal before main() runs, while the loader maps OpenImageIO's libraries, ends it quietly.)
      if grep -q "kernels:" "$work/int$i.err" && ! grep -q "rtc-render: interrupted" "$work/int$i.err"; then
        show "int$i" >&2
        fail "SIGINT after $delay s: no 'interrupted' message"
      fi
    fi
    grep -q "while frame .* was written: stopped after it" "$work/int$i.err" && wrote_through=$((wrote_through + 1))
    if [[ -n $(find "$work/i$i" -name '.*tmp*') ]]; then
      ls -la "$work/i$i" >&2
      fail "SIGINT after $delay s left a temporary file"
    fi
    for f in "$work/i$i"/f_*.exr; do
      [[ -e $f ]] || continue
      run info oiiotool --info "$f"
      [[ $rc -eq 0 && $(cat "$work/info.out") == *"1200 x  900"* ]] || { show info >&2; fail "SIGINT after $delay s: $f is not a whole frame"; }
    done
  done
  echo "an uninterrupted run took $total s; runs stopped: $stopped of $i; during a write, which was finished first: $wrote_through"
  # The check can fail: signals within the run's time must have stopped the runs.
  [[ $stopped -ge 5 ]] || fail "only $stopped of $i runs were stopped by SIGINT"
}

case_output_warnings() {
  # Options only EXR files take, given with PNG output, and a frame that already exists, are
  # warned about (both were silent); the render still succeeds.
  run first "$render" --frames 0 --width 16 --height 12 --exr-float --no-depth --out "$work/w.png"
  expect_rc first 0
  grep -q "\-\-exr-float applies to EXR output only; $work/w.png is not an EXR file" "$work/first.err" ||
    { show first >&2; fail "no warning that --exr-float does not apply to PNG"; }
  grep -q "\-\-no-depth applies to EXR output only" "$work/first.err" || { show first >&2; fail "no --no-depth warning"; }
  if grep -q "overwritten" "$work/first.err"; then show first >&2; fail "a new file was said to be overwritten"; fi
  run again "$render" --frames 0 --width 16 --height 12 --out "$work/w.png"
  expect_rc again 0
  grep -q "\-\-out: $work/w.png exists: it is overwritten" "$work/again.err" ||
    { show again >&2; fail "no warning that the existing frame is overwritten"; }
  if grep -q "applies to EXR output only" "$work/again.err"; then show again >&2; fail "a warning without the option"; fi
}

case_bad_isa() {
  expect_error isa '"avx9"' "unknown ISA" -- \
    "$render" --frames 0 --width 8 --height 8 --isa avx9 --out "$work/o.png"
  [[ ! -e $work/o.png ]] || fail "an image was written with a bad --isa"
}

case_temporal() {
  # Temporal coherence (on by default for the built-in scene's still camera): the log says how
  # many tiles each frame traced, and every frame equals a full render bit for bit.
  run inc "$render" --frames 0-5 --width 96 --height 72 --tile 16 --out "$work/i_####.png"
  expect_rc inc 0
  expect_in inc out "all 30 tiles traced (first frame)"
  expect_in inc out "tiles retraced (1 mesh and 0 lights moved"
  run full "$render" --frames 0-5 --width 96 --height 72 --tile 16 --temporal off --out "$work/f_####.png"
  expect_rc full 0
  if grep -qF "tiles retraced" "$work/full.out"; then
    show full >&2
    fail "--temporal off still retraced tiles"
  fi
  for n in 0000 0001 0002 0003 0004 0005; do
    cmp -s "$work/i_$n.png" "$work/f_$n.png" || fail "frame $n differs between --temporal on and off"
  done
  # Asked for and not possible: --temporal on for a single frame says it is off, and why.
  run one "$render" --frames 0 --temporal on --width 32 --height 24 --out "$work/one.png"
  expect_rc one 0
  expect_in one err "temporal coherence off (one frame)"
  run bad "$render" --temporal maybe --frames 0-1 --width 8 --height 8 --out "$work/b_####.png"
  [[ $rc -ne 0 ]] || fail "--temporal maybe was accepted"
  expect_in bad err "--temporal"
  [[ -z $(find "$work" -name 'b_*') ]] || fail "frames were written with a bad --temporal"
}

case_bench_json_dump() {
  [[ -n $bench ]] || fail "no rtc-bench given"
  write_small_scene
  # The dump's folder is made when missing (README's `--dump out/teapot`); one that cannot be made
  # is named before the scene loads.
  run bench "$bench" "$work/view.json" --json --mode primary --reps 2 --build-reps 1 --dump "$work/dumps/tiny"
  expect_rc bench 0
  mv "$work/dumps/tiny.t.f32" "$work/dumps/tiny.prim.u32" "$work/" || fail "no dump in the folder --dump named"
  : >"$work/in-the-way"
  expect_error bench_dump_folder "--dump: cannot make the folder $work/in-the-way" -- \
    "$bench" "$work/view.json" --mode primary --reps 1 --dump "$work/in-the-way/tiny"
  [[ -s $work/bench.out ]] || { show bench >&2; fail "no JSON printed"; }
  python3 - "$work" <<'EOF' || { show bench >&2; fail "rtc-bench JSON or dump check failed"; }
import json, math, os, struct, sys

work = sys.argv[1]
W, H = 40, 30
errors = []

lines = open(os.path.join(work, "bench.out")).read().splitlines()
if len(lines) != 1:
    errors.append(f"expected one JSON line for one mode, got {len(lines)}")
for n, line in enumerate(lines, 1):
    try:
        obj = json.loads(line)
    except json.JSONDecodeError as e:
        errors.append(f"line {n} is not JSON ({e}): {line!r}")
        continue
    for field in ("scene", "mode", "threads", "isa", "width", "height", "rays", "build_ms",
                  "mrays_per_s", "frame_ms"):
        if field not in obj:
            errors.append(f"line {n}: no field {field!r}")
    want = {"scene": "tiny_cli", "mode": "primary", "width": W, "height": H, "rays": W * H}
    for field, value in want.items():
        if obj.get(field) != value:
            errors.append(f"line {n}: {field} = {obj.get(field)!r}, expected {value!r}")
    if not (isinstance(obj.get("threads"), int) and obj["threads"] >= 1):
        errors.append(f"line {n}: threads = {obj.get('threads')!r}")
    if not (isinstance(obj.get("isa"), str) and obj["isa"]):
        errors.append(f"line {n}: isa = {obj.get('isa')!r}")
    for field in ("build_ms", "mrays_per_s", "frame_ms", "mrays_per_s_refined"):
        v = obj.get(field)
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
            errors.append(f"line {n}: {field} = {v!r} is not a finite non-negative number")

# The dump: row 0 at the top, W*H little-endian float32 / uint32.
t_bytes = open(os.path.join(work, "tiny.t.f32"), "rb").read()
p_bytes = open(os.path.join(work, "tiny.prim.u32"), "rb").read()
for name, data in (("tiny.t.f32", t_bytes), ("tiny.prim.u32", p_bytes)):
    if len(data) != W * H * 4:
        errors.append(f"{name}: {len(data)} bytes, expected {W * H * 4}")
if errors:
    print("\n".join(errors))
    sys.exit(1)
ts = struct.unpack(f"<{W * H}f", t_bytes)
prims = struct.unpack(f"<{W * H}I", p_bytes)

# Triangles in file order after fanning, the degenerate one included (it keeps its id).
verts, tris = [], []
for raw in open(os.path.join(work, "tiny.obj")):
    f = raw.split()
    if f and f[0] == "v":
        verts.append(tuple(float(x) for x in f[1:4]))
    elif f and f[0] == "f":
        idx = [int(x) - 1 for x in f[1:]]
        for k in range(1, len(idx) - 1):
            tris.append((idx[0], idx[k], idx[k + 1]))
DEGENERATE = 2
assert len(tris) == 10 and len(set(tris[DEGENERATE])) < 3

# CAMERA.md rays in double, and a brute-force closest hit (Moeller-Trumbore in double) with a
# margin: pixels whose hit lies within `margin` of an edge or tie with another triangle are
# not compared, everything else must match exactly in id and closely in t.
def sub(a, b): return (a[0] - b[0], a[1] - b[1], a[2] - b[2])
def dot(a, b): return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
def cross(a, b): return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])
def norm(a):
    l = math.sqrt(dot(a, a))
    return (a[0] / l, a[1] / l, a[2] / l)

eye, look_at, up, vfov = (0.3, 1.5, 5.0), (0.0, 0.3, 0.0), (0.0, 1.0, 0.0), 40.0
fwd = norm(sub(look_at, eye))
right = norm(cross(fwd, up))
up2 = cross(right, fwd)
h = math.tan(math.radians(vfov) / 2)
margin = 1e-3

# Every triangle the ray meets at t > 0 with all barycentrics >= -margin, as
# (t, id, smallest barycentric): a negative or small last entry is a near-edge candidate.
def trace(o, d):
    found = []
    for i, (a, b, c) in enumerate(tris):
        if i == DEGENERATE:
            continue
        A, B, C = verts[a], verts[b], verts[c]
        e1, e2 = sub(B, A), sub(C, A)
        p = cross(d, e2)
        det = dot(e1, p)
        if abs(det) < 1e-12:
            continue
        s = sub(o, A)
        u = dot(s, p) / det
        q = cross(s, e1)
        v = dot(d, q) / det
        t = dot(e2, q) / det
        edge = min(u, v, 1 - u - v)
        if edge >= -margin and t > 0:
            found.append((t, i, edge))
    found.sort()
    return found

hits = misses = compared = 0
for y in range(H):
    for x in range(W):
        i = y * W + x
        t, prim = ts[i], prims[i]
        miss = prim == 0xFFFFFFFF
        if miss != math.isinf(t) or (math.isinf(t) and t < 0) or math.isnan(t):
            errors.append(f"pixel ({x}, {y}): t = {t!r} with prim {prim:#x} (a miss is +inf with 0xFFFFFFFF)")
            continue
        if miss:
            misses += 1
        else:
            hits += 1
            if not (prim < len(tris) and prim != DEGENERATE):
                errors.append(f"pixel ({x}, {y}): triangle id {prim} is not one of the file's triangles")
            if not (t > 0):
                errors.append(f"pixel ({x}, {y}): hit at t = {t!r}")
        sx = (2 * (x + 0.5) / W - 1) * h * (W / H)
        sy = (1 - 2 * (y + 0.5) / H) * h
        d = norm(tuple(fwd[k] + sx * right[k] + sy * up2[k] for k in range(3)))
        found = trace(eye, d)
        solid = [f for f in found if f[2] >= 0]
        t_solid = solid[0][0] if solid else math.inf
        # Not compared: a near-edge candidate at or before the closest solid hit, or two
        # solid hits at nearly the same distance.
        if any(f[2] < margin and f[0] <= t_solid * (1 + margin) for f in found):
            continue
        if len(solid) > 1 and solid[1][0] - t_solid < margin * t_solid:
            continue
        compared += 1
        if solid:
            p0 = solid[0][1]
            if prim != p0 or abs(t - t_solid) > 1e-5 * t_solid:
                errors.append(f"pixel ({x}, {y}): rtc gives triangle {prim} at t = {t!r}, "
                              f"brute force triangle {p0} at t = {t_solid!r}")
        elif not miss:
            errors.append(f"pixel ({x}, {y}): rtc hits triangle {prim} at t = {t!r}, brute force misses")

if hits == 0 or misses == 0:
    errors.append(f"the scene should give both hits and misses: {hits} hits, {misses} misses")
if compared < W * H * 0.9:
    errors.append(f"only {compared} of {W * H} pixels were clear enough to compare")
if errors:
    print("\n".join(errors[:20]))
    if len(errors) > 20:
        print(f"... and {len(errors) - 20} more")
    sys.exit(1)
print(f"dump ok: {hits} hits, {misses} misses, {compared} pixels checked against brute force")
EOF
}

case_bench_embree() {
  [[ -n $bench ]] || fail "no rtc-bench given"
  write_small_scene
  run bench "$bench" "$work/view.json" --json --mode primary --reps 1 --compare-embree
  expect_rc bench 0
  python3 - "$work/bench.out" <<'EOF' || { show bench >&2; fail "Embree agreement check failed"; }
import json, sys
lines = open(sys.argv[1]).read().splitlines()
assert len(lines) == 1, f"expected one JSON line, got {len(lines)}"
obj = json.loads(lines[0])
emb = obj.get("embree")
assert isinstance(emb, dict) and "embree-1" in emb, f"no embree-1 figures: {emb!r}"
single = emb["embree-1"]
agreement = single.get("hit_miss_agreement")
assert agreement == 1.0, f"embree-1 hit_miss_agreement = {agreement!r}, expected 1.0"
assert single.get("unexplained") == 0, f"embree-1 unexplained = {single.get('unexplained')!r}"
for mode, figures in emb.items():
    assert figures.get("hit_miss_agreement") == 1.0, f"{mode}: {figures!r}"
print(f"embree agreement ok: {single}")
EOF
}

case_deterministic_across_processes() {
  local common=(--frames 3 --exr-float)
  run a "$render" "${common[@]}" --threads 1 --tile 7 --out "$work/a.exr"
  expect_rc a 0
  run b "$render" "${common[@]}" --threads 2 --tile 64 --out "$work/b.exr"
  expect_rc b 0
  run c "$render" "${common[@]}" --single-rays --out "$work/c.exr"
  expect_rc c 0
  local other
  for other in b c; do
    run "diff_$other" oiiotool "$work/a.exr" "$work/$other.exr" --fail 0 --warn 0 --diff
    if [[ $rc -ne 0 ]]; then
      show "$other" >&2
      show "diff_$other" >&2
      fail "frame 3 differs between '--threads 1 --tile 7' (a) and run $other"
    fi
  done
  # The comparison can fail: frame 4 (the gold sphere has moved) must differ from frame 3.
  run d "$render" --frames 4 --exr-float --out "$work/d.exr"
  expect_rc d 0
  run diff_d oiiotool "$work/a.exr" "$work/d.exr" --fail 0 --warn 0 --diff
  [[ $rc -ne 0 ]] || fail "frames 3 and 4 compare equal: the diff check is not checking"
}

if ! declare -F "case_$test_case" >/dev/null; then
  echo "unknown case '$test_case'" >&2
  exit 2
fi
"case_$test_case"
echo "PASS [$test_case]"
