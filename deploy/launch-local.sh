#!/usr/bin/env bash
# One command for a local cluster: starts rtc-master plus N rtc-worker processes on this machine
# (loopback, a free port), prints the master's frame-rate log, and leaves no process behind on
# exit, error or Ctrl-C (Ctrl-C: the master finishes the frames in flight, then all stop).
#
# Usage: ./deploy/launch-local.sh [N] [SCENE] [-- extra rtc-master args]
#   N      workers (default: the machine's core count); each gets cores/N threads (at least 1);
#          a first argument that is not a number is the SCENE
#   SCENE  scene file (default: the built-in scene, its whole animation)
#   extra  e.g. -- --frames 0-9 --wire half --compress lz4 --out out/f_####.exr --stats-json s.jsonl
# Frames go to out/cluster/<scene>_NNNN.png (rtc-master --out-dir: <scene> is the scene's name as
# rtc-render names its frames) unless the extra args give --out or --out-dir; --no-out among them
# (taken by this script) writes no frames at all: a frame-rate run. --min-workers among them
# replaces the default, N.
# Binaries come from $RTC_BUILD_DIR; by default build/release when it has them, else
# build/programs (what ./deploy/run-default.sh builds). Missing ones are built there (the
# `release` preset for a folder named release, else `programs`, which needs only the packages of
# ./deploy/install-deps.sh --build-only).
# Ctrl-C (SIGINT to this script's process group) and SIGTERM to the script or its group are passed
# on to the master, once per signal: the first makes it finish the frames in flight, then
# everything stops; a second abandons them.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
if [ -n "${RTC_BUILD_DIR:-}" ]; then
  build="$(realpath -m -- "$RTC_BUILD_DIR")"
elif [ -x "$root/build/release/master/rtc-master" ]; then
  build="$root/build/release"
else
  build="$root/build/programs"
fi

workers="$(nproc)"
scene=()
# A scene without N: the first argument names a file and is not a number.
if [ $# -gt 0 ] && [ "$1" != "--" ] && ! [[ "$1" =~ ^[0-9]+$ ]]; then
  if [ ! -f "$1" ]; then
    echo "launch-local: \"$1\" is neither a number of workers nor a scene file (usage: launch-local.sh [N] [SCENE] [-- rtc-master args])" >&2
    exit 2
  fi
  scene=("$1")
  shift
fi
if [ ${#scene[@]} -eq 0 ] && [ $# -gt 0 ] && [ "$1" != "--" ]; then
  if [[ "$1" =~ ^0+$ ]]; then
    echo "launch-local: N must be a positive number of workers, got \"$1\"" >&2
    exit 2
  fi
  # Each worker is a process with at least one render thread on this machine: far more than
  # the cores only slows the frames down (and takes a long time to start and stop).
  max_workers=$((8 * $(nproc)))
  if ! [[ "$1" =~ ^0*[0-9]{1,6}$ ]] || [ "$((10#$1))" -gt "$max_workers" ]; then
    echo "launch-local: N = $1 workers on $(nproc) cores: at most $max_workers (8 a core); for more, start rtc-worker on other machines" >&2
    exit 2
  fi
  workers="$((10#$1))"
  shift
fi
if [ ${#scene[@]} -eq 0 ] && [ $# -gt 0 ] && [ "$1" != "--" ]; then
  [ -f "$1" ] || { echo "launch-local: scene file $1 does not exist" >&2; exit 2; }
  scene=("$1")
  shift
fi
[ $# -gt 0 ] && [ "$1" = "--" ] && shift
extra=("$@")

if [ ! -x "$build/master/rtc-master" ] || [ ! -x "$build/worker/rtc-worker" ]; then
  preset=programs
  [ "$(basename "$build")" = release ] && preset=release
  echo "launch-local: building rtc-master and rtc-worker in $build (preset $preset)"
  (cd "$root" && cmake --preset "$preset" -B "$build" >/dev/null && cmake --build "$build" --target rtc-master rtc-worker)
fi

has_out=0
has_min_workers=0
master_args=()
for a in "${extra[@]}"; do
  case "$a" in
    --no-out) has_out=1; continue ;;  # this script's own: no --out added, frames not written
    --out | --out=* | --out-dir | --out-dir=*) has_out=1 ;;
    --min-workers | --min-workers=*) has_min_workers=1 ;;
    --listen | --listen=* | --ready-file | --ready-file=*)
      echo "launch-local: $a is this script's own (the master listens on a free loopback port); start rtc-master by hand to choose it" >&2
      exit 2 ;;
  esac
  master_args+=("$a")
done
if [ "$has_out" = 0 ]; then
  mkdir -p out/cluster
  master_args+=(--out-dir out/cluster)
fi
[ "$has_min_workers" = 1 ] || master_args+=(--min-workers "$workers")

cores="$(nproc)"
threads=$(( cores / workers ))
[ "$threads" -ge 1 ] || threads=1
run_dir="$(mktemp -d "${TMPDIR:-/tmp}/rtc-local.XXXXXX")"
master_pid=""
worker_pids=()
workers_started=0

cleanup() {
  local status=$?
  trap - EXIT INT TERM
  if [ -n "$master_pid" ] && kill -0 "$master_pid" 2>/dev/null; then
    kill -TERM "$master_pid" 2>/dev/null || true
    wait "$master_pid" 2>/dev/null || true
  fi
  for pid in "${worker_pids[@]}"; do kill -TERM "$pid" 2>/dev/null || true; done
  for pid in "${worker_pids[@]}"; do
    for _ in $(seq 1 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "$pid" 2>/dev/null || true
    wait "$pid" 2>/dev/null || true
  done
  if [ "$status" -ne 0 ] && [ "$workers_started" = 1 ]; then
    echo "launch-local: worker logs kept in $run_dir" >&2
  else
    rm -rf "$run_dir"
  fi
  exit "$status"
}
trap cleanup EXIT
# The master and the workers run in sessions of their own, so a signal to this script's process
# group (Ctrl-C, `kill %1`, `timeout`, a supervisor) reaches only the script, which passes each
# SIGINT or SIGTERM on to the master exactly once: the first makes it finish the frames in flight
# with the workers, a second abandons them. One that comes before the master is started is passed
# on as soon as it is (before the master has loaded the scene, it simply ends it).
interrupted=0
signals=0
pending=()
forward() {
  interrupted=1
  signals=$((signals + 1))
  if [ "$signals" -eq 1 ]; then
    echo "launch-local: SIG$1: stopping (the master finishes the frames in flight; signal again to abandon them)" >&2
  else
    echo "launch-local: SIG$1 again: the master abandons the frames in flight" >&2
  fi
  if [ -n "$master_pid" ]; then kill -"$1" "$master_pid" 2>/dev/null || true; else pending+=("$1"); fi
}
trap 'forward INT' INT
trap 'forward TERM' TERM

setsid "$build/master/rtc-master" "${scene[@]}" --listen 127.0.0.1:0 --ready-file "$run_dir/address" "${master_args[@]}" &
master_pid=$!
for sig in "${pending[@]}"; do kill -"$sig" "$master_pid" 2>/dev/null || true; done
for _ in $(seq 1 600); do
  [ -s "$run_dir/address" ] && break
  kill -0 "$master_pid" 2>/dev/null || { wait "$master_pid"; exit $?; }
  sleep 0.1
done
[ -s "$run_dir/address" ] || { echo "launch-local: the master did not start listening within 60 s" >&2; exit 1; }
address="$(cat "$run_dir/address")"
echo "launch-local: master on $address; starting $workers worker$([ "$workers" = 1 ] || echo s) with $threads" \
  "thread$([ "$threads" = 1 ] || echo s) each (logs in $run_dir)"
workers_started=1
for i in $(seq 1 "$workers"); do
  setsid "$build/worker/rtc-worker" --connect "$address" --threads "$threads" --name "local-$i" \
    --retry-seconds 10 > "$run_dir/worker-$i.log" 2>&1 &
  worker_pids+=($!)
done

# The master's own exit status. A trapped signal cuts `wait` short (status 128 + signal) whether
# or not the master is still running, so wait again after one: the master's status stays there
# to be collected (it may well have exited by then: it finishes its frames in milliseconds), and
# 127 means the wait before the signal already collected it.
status=0
while :; do
  interrupted=0
  rc=0
  wait "$master_pid" || rc=$?
  [ "$rc" -eq 127 ] && break
  status=$rc
  [ "$interrupted" -eq 1 ] || break
done
[ "$status" -eq 0 ] || echo "launch-local: rtc-master exited with status $status" >&2
exit "$status"
