#!/usr/bin/env bash
# One command for a local cluster: starts rtc-master plus N rtc-worker processes on this machine
# (loopback, a free port), prints the master's frame-rate log, and leaves no process behind on
# exit, error or Ctrl-C (Ctrl-C: the master finishes the frames in flight, then all stop).
#
# Usage: ./deploy/launch-local.sh [N] [SCENE] [-- extra rtc-master args]
#   N      workers (default: the machine's core count, at most 8 a core); each gets cores/N
#          threads (at least 1); a first argument that is not a number is the SCENE
#   SCENE  scene file, or a folder holding view.json (default: the built-in scene, its whole
#          animation)
#   extra  e.g. -- --frames 0-9 --wire half --compress lz4 --out out/f_####.exr --stats-json s.jsonl
#          (--out's folder must exist; --listen and --ready-file are the script's own, and a
#          --min-workers above N is refused: the master would wait for ever; --token-file F is
#          passed on to the workers too, --tls-cert C makes them trust C, and --tls-server-name
#          NAME, the workers' alone, is the name C carries if not 127.0.0.1)
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
# A worker that fails (exits non-zero before the master) is reported with the end of its log, one
# stopped from outside is named; when fewer workers are left than --min-workers the master is
# stopped (it finishes the frames in flight; with no worker left, it abandons them after its
# --drain-seconds). Exit status: 1 when a worker failed or the master had to be stopped for want
# of workers (a Ctrl-C after that too; the logs are kept then) unless the master itself failed,
# else the master's: 130 or 143 when a Ctrl-C or SIGTERM cut the run short.
set -euo pipefail
usage() { sed -n '2,/^set -euo/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'; }
root="$(cd "$(dirname "$0")/.." && pwd)"
if [ -n "${RTC_BUILD_DIR:-}" ]; then
  build="$(realpath -m -- "$RTC_BUILD_DIR")"
elif [ -x "$root/build/release/master/rtc-master" ]; then
  build="$root/build/release"
else
  build="$root/build/programs"
fi

# An option before `--` is rtc-master's, given in the wrong place (or --help).
for a in "$@"; do
  [ "$a" = "--" ] && break
  case "$a" in -h | --help) usage; exit 0 ;; esac
  if [[ "$a" =~ ^-[0-9]+$ ]]; then
    echo "launch-local: N must be a positive number of workers, got \"$a\"" >&2
    exit 2
  fi
  if [[ "$a" == -* ]]; then
    echo "launch-local: $a: rtc-master's options go after -- (usage: launch-local.sh [N] [SCENE] [-- rtc-master args]; --help for more)" >&2
    exit 2
  fi
done
workers="$(nproc)"
scene=()
# A scene: a file, or a folder holding view.json (a scene pack, e.g. ../shared/scenes/bunny).
is_scene() { [ -f "$1" ] || { [ -d "$1" ] && [ -f "$1/view.json" ]; }; }
# A scene without N: the first argument names a file and is not a number.
if [ $# -gt 0 ] && [ "$1" != "--" ] && ! [[ "$1" =~ ^[0-9]+$ ]]; then
  if ! is_scene "$1"; then
    echo "launch-local: \"$1\" is neither a number of workers nor a scene file or folder with a view.json (usage: launch-local.sh [N] [SCENE] [-- rtc-master args])" >&2
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
  if ! is_scene "$1"; then
    if [ -d "$1" ]; then
      echo "launch-local: scene folder $1 has no view.json" >&2
    else
      echo "launch-local: scene file $1 does not exist" >&2
    fi
    exit 2
  fi
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
min_workers="$workers"
master_args=()
worker_args=()
# The value of an option given as `--name VALUE` or `--name=VALUE`, at extra[i]: sets `value`
# and `used` (1 or 2 arguments).
option_value() {
  local i=$1 name=$2
  if [ "${extra[$i]}" = "$name" ]; then
    if [ $((i + 1)) -ge ${#extra[@]} ]; then
      echo "launch-local: $name needs a value" >&2
      exit 2
    fi
    value="${extra[$((i + 1))]}"
    used=2
  else
    value="${extra[$i]#"$name="}"
    used=1
  fi
}
i=0
while [ "$i" -lt ${#extra[@]} ]; do
  a="${extra[$i]}"
  used=1
  case "$a" in
    --no-out) has_out=1; i=$((i + 1)); continue ;;  # this script's own: no --out added, frames not written
    --out | --out=* | --out-dir | --out-dir=*) has_out=1 ;;
    --min-workers | --min-workers=*)
      option_value "$i" --min-workers
      has_min_workers=1
      # (A value that is no number is the master's to refuse.)
      if [[ "$value" =~ ^[0-9]{1,6}$ ]]; then
        min_workers="$((10#$value))"
        # The master waits for that many before it starts: more than this script starts is a wait for ever.
        if [ "$min_workers" -gt "$workers" ]; then
          echo "launch-local: --min-workers $value but $workers worker$([ "$workers" = 1 ] || echo s) started here: the master would wait for ever (give N >= $value)" >&2
          exit 2
        fi
      fi ;;
    --token-file | --token-file=*)
      # The workers must prove the same token.
      option_value "$i" --token-file
      worker_args+=(--token-file "$value") ;;
    --tls-cert | --tls-cert=*)
      # The workers must trust the master's certificate; they connect to 127.0.0.1, so it must name
      # that address (rtc-worker says so when it does not).
      option_value "$i" --tls-cert
      worker_args+=(--tls-ca "$value") ;;
    --tls-server-name | --tls-server-name=*)
      # The workers' own: the name the certificate carries when it does not name 127.0.0.1.
      option_value "$i" --tls-server-name
      worker_args+=(--tls-server-name "$value")
      i=$((i + used))
      continue ;;
    --listen | --listen=* | --ready-file | --ready-file=*)
      echo "launch-local: $a is this script's own (the master listens on a free loopback port); start rtc-master by hand to choose it" >&2
      exit 2 ;;
  esac
  master_args+=("${extra[@]:$i:$used}")
  i=$((i + used))
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
worker_pids=()  # the workers not yet collected
declare -A worker_name=()  # pid -> local-i
workers_started=0
workers_failed=0

# A worker has exited with `rc`: a failure unless 0. Status 0 is a goodbye from the master (the
# run is ending: its log says so) or a worker stopped from outside (a signal, on which it says
# goodbye itself). Returns 1 when the workers left must be judged (judge_workers, below).
worker_exited() {
  local pid=$1 rc=$2 name="${worker_name[$1]}"
  local log="$run_dir/worker-${name#local-}.log"
  local kept=()
  for p in "${worker_pids[@]}"; do [ "$p" = "$pid" ] || kept+=("$p"); done
  worker_pids=("${kept[@]}")
  if [ "$rc" -eq 0 ]; then
    # (Only grep's "not found" counts: a Ctrl-C may kill grep itself.)
    local found=0
    grep -q " said goodbye: " "$log" 2>/dev/null || found=$?
    [ "$found" -eq 1 ] || return 0
    echo "launch-local: worker $name (pid $pid) left (stopped from outside)" >&2
    return 1
  fi
  workers_failed=$((workers_failed + 1))
  echo "launch-local: worker $name (pid $pid) exited with status $rc; the end of its log ($log):" >&2
  { tail -n 8 "$log" | sed 's/^/  | /' >&2; } || true
  return 1
}

# Collects every worker that has exited (`collected` says whether any had), by pid: bash drops a
# job killed by a signal while the script was not waiting (it reports it), and `wait -n` no
# longer sees it; `wait PID` still has its status. Returns 1 when the workers left must be judged.
collect_exited_workers() {
  local pid rc judge=0
  collected=0
  for pid in "${worker_pids[@]}"; do
    kill -0 "$pid" 2>/dev/null && continue
    rc=0
    wait "$pid" 2>/dev/null || rc=$?
    worker_exited "$pid" "$rc" || judge=1
    collected=1
  done
  return "$judge"
}

cleanup() {
  local status=$?
  # Bounded (the master 10 s, then KILL; the workers 5 s): a signal now would end the script
  # with its processes still running.
  trap - EXIT
  trap '' INT TERM
  if [ -n "$master_pid" ] && kill -0 "$master_pid" 2>/dev/null; then
    kill -TERM "$master_pid" 2>/dev/null || true
    for _ in $(seq 1 100); do kill -0 "$master_pid" 2>/dev/null || break; sleep 0.1 || true; done
    kill -KILL "$master_pid" 2>/dev/null || true
    wait "$master_pid" 2>/dev/null || true
  fi
  # Workers that exited by themselves (a goodbye from the master, or a failure) are collected with
  # their status; the rest are stopped.
  collect_exited_workers || true
  for pid in "${worker_pids[@]}"; do kill -TERM "$pid" 2>/dev/null || true; done
  # 5 s for all of them together, then KILL.
  for _ in $(seq 1 50); do
    local alive=0
    for pid in "${worker_pids[@]}"; do kill -0 "$pid" 2>/dev/null && alive=1 && break; done
    [ "$alive" = 1 ] || break
    sleep 0.1 || true
  done
  for pid in "${worker_pids[@]}"; do
    kill -KILL "$pid" 2>/dev/null || true
    wait "$pid" 2>/dev/null || true
  done
  # A master cut short by a signal (130, 143) after a worker failed, or stopped by the script
  # for want of workers (a SIGTERM, then perhaps the user's Ctrl-C): the status says that (1).
  local whole_or_signalled=0
  if [ "$status" -eq 0 ] || [ "$status" -eq 130 ] || [ "$status" -eq 143 ]; then whole_or_signalled=1; fi
  if [ "$whole_or_signalled" = 1 ] && [ "$workers_failed" -gt 0 ]; then
    echo "launch-local: $workers_failed worker$([ "$workers_failed" = 1 ] || echo s) failed" >&2
    status=1
  elif [ "$whole_or_signalled" = 1 ] && [ "$stopped_for_workers" = 1 ]; then
    echo "launch-local: the run was stopped for want of workers" >&2
    status=1
  fi
  # A run the user stopped, with nothing failed, keeps no logs.
  local stopped_by_user=0
  if [ -n "$user_signal" ] && [ "$workers_failed" = 0 ] && [ "$stopped_for_workers" = 0 ] &&
    { [ "$status" -eq 130 ] || [ "$status" -eq 143 ]; }; then
    stopped_by_user=1
  fi
  if [ "$status" -ne 0 ] && [ "$workers_started" = 1 ] && [ "$stopped_by_user" = 0 ]; then
    echo "launch-local: worker logs kept in $run_dir" >&2
  else
    rm -rf "$run_dir"
  fi
  exit "$status"
}
stopped_for_workers=0
user_signal=""  # the first SIGINT or SIGTERM the script got (INT, TERM)
trap cleanup EXIT
# The master and the workers run in sessions of their own, so a signal to this script's process
# group (Ctrl-C, `kill %1`, `timeout`, a supervisor) reaches only the script, which passes each
# SIGINT or SIGTERM on to the master exactly once: the first makes it finish the frames in flight
# with the workers, a second abandons them. One that comes before the master is started is passed
# on as soon as it is (before the master has loaded the scene, it simply ends it). The script's
# own stops (workers missing, below) count as such signals too. Short commands the script runs
# meanwhile (sleep, tail) are in the group and die of a Ctrl-C: `|| true` keeps `set -e` from
# ending the script there.
interrupted=0
signals=0
pending=()
# Sends SIGTERM or SIGINT to the master as the next signal of the count above.
signal_master() {
  signals=$((signals + 1))
  if [ -n "$master_pid" ]; then kill -"$1" "$master_pid" 2>/dev/null || true; else pending+=("$1"); fi
}
forward() {
  interrupted=1
  [ -n "$user_signal" ] || user_signal="$1"
  if [ "$signals" -eq 0 ]; then
    echo "launch-local: SIG$1: stopping (the master finishes the frames in flight; signal again to abandon them)" >&2
  else
    echo "launch-local: SIG$1 again: the master abandons the frames in flight" >&2
  fi
  signal_master "$1"
}
trap 'forward INT' INT
trap 'forward TERM' TERM

# A non-interactive bash starts background jobs with SIGINT ignored, which the master would keep
# until it sets its own handler after loading the scene: a Ctrl-C during the load was lost.
env --default-signal=INT setsid "$build/master/rtc-master" "${scene[@]}" --listen 127.0.0.1:0 --ready-file "$run_dir/address" "${master_args[@]}" &
master_pid=$!
for sig in "${pending[@]}"; do kill -"$sig" "$master_pid" 2>/dev/null || true; done
# The master loads the scene before it listens: however long that takes, while it runs.
waited=0
until [ -s "$run_dir/address" ]; do
  kill -0 "$master_pid" 2>/dev/null || { rc=0; wait "$master_pid" || rc=$?; master_pid=""; exit "$rc"; }
  sleep 0.1 || true
  waited=$((waited + 1))
  [ $((waited % 300)) -ne 0 ] || echo "launch-local: waiting for the master to load the scene and listen ($((waited / 10)) s)" >&2
done
address=""
read -r address < "$run_dir/address" || true
echo "launch-local: master on $address; starting $workers worker$([ "$workers" = 1 ] || echo s) with $threads" \
  "thread$([ "$threads" = 1 ] || echo s) each (logs in $run_dir)"
workers_started=1
for i in $(seq 1 "$workers"); do
  setsid "$build/worker/rtc-worker" --connect "$address" --threads "$threads" --name "local-$i" \
    --retry-seconds 10 "${worker_args[@]}" > "$run_dir/worker-$i.log" 2>&1 &
  worker_pids+=($!)
  worker_name[$!]="local-$i"
done

# With fewer workers than --min-workers the master waits for ever (it starts only with them) or
# goes on with fewer; with none it renders nothing. One SIGTERM, never a second: it finishes the
# frames in flight (or, with no worker, abandons them after its --drain-seconds) and writes every
# finished frame, also when the run was ending anyway.
judge_workers() {
  local left=${#worker_pids[@]}
  { [ "$left" -lt "$min_workers" ] && [ "$signals" -eq 0 ]; } || return 0
  if [ "$left" -eq 0 ]; then
    echo "launch-local: no worker left; stopping the master (frames in flight are abandoned after its --drain-seconds)" >&2
  else
    echo "launch-local: $left worker$([ "$left" = 1 ] || echo s) left, fewer than --min-workers $min_workers; stopping the master (it finishes the frames in flight)" >&2
  fi
  stopped_for_workers=1
  signal_master TERM
}

# Wait for the master or a worker, whichever exits first. A trapped signal cuts `wait` short
# (status 128 + signal, `done_pid` unset) whether or not they still run: wait again then; an
# exited process's status stays there to be collected.
status=0
while :; do
  # The master as the workers below (collect_exited_workers).
  if ! kill -0 "$master_pid" 2>/dev/null; then
    rc=0
    wait "$master_pid" 2>/dev/null || rc=$?
    status=$rc
    master_pid=""
    break
  fi
  collect_exited_workers || judge_workers
  # Only builtins between the last check and the wait: a process that dies while grep or tail
  # runs is checked for again first.
  [ "$collected" = 0 ] || continue
  interrupted=0
  rc=0
  done_pid=""
  wait -n -p done_pid "$master_pid" "${worker_pids[@]}" 2>/dev/null || rc=$?
  if [ -z "${done_pid:-}" ]; then
    [ "$interrupted" -eq 1 ] || sleep 0.1 || true  # (nothing to wait for: collected above next)
    continue
  fi
  if [ "$done_pid" = "$master_pid" ]; then
    status=$rc
    master_pid=""
    break
  fi
  worker_exited "$done_pid" "$rc" || judge_workers
done
if [ "$status" -eq 130 ] || [ "$status" -eq 143 ]; then
  # (After a worker failed or the script stopped the master, cleanup says so, with status 1.)
  if [ "$workers_failed" = 0 ] && [ "$stopped_for_workers" = 0 ]; then
    if [ -n "$user_signal" ]; then
      echo "launch-local: the run was cut short by SIG$user_signal (rtc-master's status $status)" >&2
    else
      echo "launch-local: rtc-master exited with status $status (a signal from outside the script cut its run short)" >&2
    fi
  fi
elif [ "$status" -ne 0 ]; then
  echo "launch-local: rtc-master exited with status $status" >&2
fi
exit "$status"
