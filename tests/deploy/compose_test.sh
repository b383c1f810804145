#!/usr/bin/env bash
# The compose cluster for real: starts a Docker engine when none answers, makes the base images
# when missing (deploy/make-base-image.sh), builds deploy/Dockerfile through docker-compose,
# brings up a master and 3 workers (deploy/compose.sh) on the built-in scene plus one worker on
# the host that joins through the master's published 127.0.0.1 port with the token, checks the
# Docker health checks, and requires every frame on the host to equal rtc-render's bit for bit
# and `compose.sh up` (in the foreground) to exit 0. Then `down`; a run whose master fails must
# exit with its status, and one whose worker fails with 1, each naming what failed. On every exit
# path everything it made goes: containers, network, images, base images, the engine it started
# (with its data, mounts and interfaces). Prints MEASURE lines (build time, image size, start-up).
# Exit 0 pass, 1 fail, 77 skip (only when no engine can be started).
#
# usage: compose_test.sh --render RTC_RENDER --worker RTC_WORKER --oiiotool OIIOTOOL [--keep]
#   --keep  leave the work folder (logs, frames) and print where it is
# Env: RTC_DEPLOY_TEST_FRAMES (0-3) frames rendered; the engine's DOCKER_HOST when one runs elsewhere.
set -euo pipefail

here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
render="" worker="" oiiotool="" keep=0
while [ $# -gt 0 ]; do
  case "$1" in
    --render) render="$2"; shift 2 ;;
    --worker) worker="$2"; shift 2 ;;
    --oiiotool) oiiotool="$2"; shift 2 ;;
    --keep) keep=1; shift ;;
    *) echo "compose_test: unknown argument \"$1\"" >&2; exit 2 ;;
  esac
done
if [ ! -x "$render" ] || [ ! -x "$worker" ] || [ ! -x "$oiiotool" ]; then
  echo "usage: compose_test.sh --render RTC_RENDER --worker RTC_WORKER --oiiotool OIIOTOOL [--keep]" >&2
  exit 2
fi

frames="${RTC_DEPLOY_TEST_FRAMES:-0-3}"
first="${frames%-*}" last="${frames#*-}"
workers=3
project="rtctest$$"
image="rtc-compose-test:$$"
test_start=$SECONDS
export DOCKER_BUILDKIT=0 COMPOSE_DOCKER_CLI_BUILD=0  # the legacy builder: the Dockerfile must not need BuildKit

work="$(mktemp -d "${TMPDIR:-/tmp}/rtc-compose.XXXXXX")"
engine="$work/engine"
engine_pid=""
made_base=0
compose_up=0
host_worker_pid=""
images_before=""
bridge=""
status=0

say() { echo "compose_test: $*"; }
fail() { echo "compose_test: FAIL: $*" >&2; exit 1; }
skip() { echo "compose_test: SKIP: $*"; exit 77; }
measure() { echo "MEASURE $*"; }
compose() { timeout "${COMPOSE_TIMEOUT:-120}" "$root/deploy/compose.sh" -p "$project" "$@"; }
# Runs a long step in the background and waits for it: bash runs a signal's trap only after a
# foreground command ends, but at once during `wait`.
in_background() {
  "$@" &
  local pid=$! rc=0
  wait "$pid" || rc=$?
  return "$rc"
}
# Every process this script started that is still running (the engine and the watchdog are not
# among them: they left the process tree).
descendants() {
  local child
  for child in $(ps -o pid= --ppid "$1"); do
    echo "$child"
    descendants "$child"
  done
}

# ---- cleanup, on every exit path ---------------------------------------------------------------

stop_engine() {
  [ -n "$engine_pid" ] || return 0
  say "stopping the Docker engine it started (pid $engine_pid)"
  local containerd_pid=""
  containerd_pid="$(cat "$engine/exec/containerd/containerd.pid" 2>/dev/null || true)"
  kill -TERM "$engine_pid" 2>/dev/null || true
  for _ in $(seq 1 60); do kill -0 "$engine_pid" 2>/dev/null || break; sleep 0.5; done
  if kill -0 "$engine_pid" 2>/dev/null; then
    echo "compose_test: dockerd (pid $engine_pid) ignored SIGTERM for 30 s; killing it" >&2
    kill -KILL "$engine_pid" 2>/dev/null || true
    status=1
  fi
  if [ -n "$containerd_pid" ] && kill -0 "$containerd_pid" 2>/dev/null; then
    for _ in $(seq 1 20); do kill -0 "$containerd_pid" 2>/dev/null || break; sleep 0.5; done
    kill -KILL "$containerd_pid" 2>/dev/null || true
  fi
  engine_pid=""
  # dockerd leaves its network-namespace mount (and, when killed, more) under its roots.
  findmnt -rn -o TARGET | grep "^$engine/" | sort -r | while read -r m; do umount -l "$m" 2>/dev/null || true; done
  rm -rf "$engine"
}

cleanup() {
  local rc=$?
  [ "$status" -ne 0 ] || status=$rc
  trap - EXIT INT TERM
  set +e
  # A step cut short by a signal (a build, a wait) and the host worker.
  local running pid alive
  mapfile -t running < <(descendants $$)
  if [ ${#running[@]} -gt 0 ]; then
    kill -TERM "${running[@]}" 2>/dev/null
    for _ in $(seq 1 20); do
      alive=0
      for pid in "${running[@]}"; do kill -0 "$pid" 2>/dev/null && alive=1; done
      [ "$alive" = 1 ] || break
      sleep 0.25
    done
    kill -KILL "${running[@]}" 2>/dev/null
  fi
  if [ "$compose_up" = 1 ]; then
    compose down --volumes --remove-orphans --timeout 10 > "$work/down.log" 2>&1 ||
      { cat "$work/down.log" >&2; echo "compose_test: compose down failed" >&2; status=1; }
  fi
  if docker info >/dev/null 2>&1; then
    left="$(docker ps -aq --filter "label=com.docker.compose.project=$project")"
    [ -z "$left" ] || { echo "compose_test: containers left: $left" >&2; xargs docker rm -f <<<"$left" >/dev/null; status=1; }
    docker network rm "${project}_default" >/dev/null 2>&1
    # What this run built: its image, the build's cache images, the base images if it made them.
    docker image rm -f "$image" >/dev/null 2>&1
    if [ -n "$images_before" ]; then
      new_images() { docker images -aq --no-trunc | sort -u | grep -vxF "$images_before"; }
      for id in $(new_images); do docker image rm "$id" >/dev/null 2>&1; done
      [ -z "$(new_images)" ] || echo "compose_test: warning: images made during the run are still there: $(new_images)" >&2
    fi
    [ "$made_base" = 0 ] || docker image rm debian:bookworm debian:bookworm-slim >/dev/null 2>&1
  fi
  stop_engine
  if [ -n "$bridge" ] && ip link show "$bridge" >/dev/null 2>&1; then
    echo "compose_test: the compose network's bridge $bridge is still there; deleting it" >&2
    ip link delete "$bridge"
    status=1
  fi
  if [ -n "${forward_before:-}" ] && [ "$(cat /proc/sys/net/ipv4/ip_forward)" != "$forward_before" ]; then
    echo "compose_test: net.ipv4.ip_forward changed; restoring $forward_before" >&2
    echo "$forward_before" > /proc/sys/net/ipv4/ip_forward
    status=1
  fi
  if [ -n "${iptables_before+set}" ] && [ "$(iptables_rules)" != "$iptables_before" ]; then
    echo "compose_test: iptables rules changed:" >&2
    diff <(echo "$iptables_before") <(iptables_rules) >&2
    status=1
  fi
  # Kept for a look when a check failed (not when skipped or interrupted).
  if [ "$keep" = 1 ] || { [ "$status" -ne 0 ] && [ "$status" -ne 77 ] && [ "$status" -ne 130 ] && [ "$status" -ne 143 ]; }; then
    say "work folder kept: $work"
  else
    rm -rf "$work"
  fi
  say "took $((SECONDS - test_start)) s in all"
  exit "$status"
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

# --help prints the script's usage and makes nothing (no token, no frames folder), with or
# without an engine.
help_text="$(RTC_FRAMES_DIR="$work/help-frames" RTC_TOKEN_FILE="$work/help-token" "$root/deploy/compose.sh" --help)" ||
  fail "compose.sh --help exited with status $?"
case "$help_text" in *"Usage: ./deploy/compose.sh up"*) ;; *) fail "compose.sh --help printed no usage: $help_text" ;; esac
if [ -e "$work/help-frames" ] || [ -e "$work/help-token" ]; then fail "compose.sh --help made the frames folder or the token"; fi
say "compose.sh --help: its usage, nothing made"

iptables_rules() { { iptables -S; iptables -t nat -S; } 2>/dev/null; }

# ---- tools ----------------------------------------------------------------------------------------

for tool in docker docker-compose; do
  command -v "$tool" >/dev/null 2>&1 || fail "$tool is not installed (./deploy/install-deps.sh installs docker.io and docker-compose)"
done

# ---- engine: the one that answers, or one of our own -------------------------------------------
# Our own runs beside anything else: its own socket, data and state folders, and no docker0,
# iptables rules or IP forwarding (compose's network is a plain bridge; builds use the host's
# network), so stopping it and deleting its folder takes everything it made.

if docker info >/dev/null 2>&1; then
  say "using the Docker engine that answers ($(docker context show 2>/dev/null || echo default))"
else
  [ "$(id -u)" -eq 0 ] || skip "no Docker engine answers, and starting one needs root"
  command -v dockerd >/dev/null 2>&1 || fail "dockerd is not installed (./deploy/install-deps.sh installs docker.io)"
  forward_before="$(cat /proc/sys/net/ipv4/ip_forward)"
  iptables_before="$(iptables_rules)"
  mkdir -p "$engine"
  export DOCKER_HOST="unix://$engine/docker.sock"
  ( setsid dockerd --data-root "$engine/root" --exec-root "$engine/exec" --pidfile "$engine/dockerd.pid" \
      --host "$DOCKER_HOST" --bridge=none --iptables=false --ip-masq=false --ip-forward=false \
      > "$work/dockerd.log" 2>&1 & echo $! > "$work/dockerd.spawned" )
  engine_pid="$(cat "$work/dockerd.spawned")"
  # A watchdog outside this process tree stops the engine should this script be killed outright
  # (SIGKILL, as ctest does at its timeout) before its own cleanup runs.
  # shellcheck disable=SC2016  # expanded by the watchdog shell
  ( setsid bash -c '
      test_pid=$1 engine=$2 pid=$3
      while kill -0 "$test_pid" 2>/dev/null; do sleep 1; done
      [ -d "$engine" ] || exit 0
      echo "compose_test watchdog: the test died; stopping its Docker engine (pid $pid)" >&2
      kill -TERM "$pid" 2>/dev/null
      for _ in $(seq 1 60); do kill -0 "$pid" 2>/dev/null || break; sleep 0.5; done
      kill -KILL "$pid" 2>/dev/null
      findmnt -rn -o TARGET | grep "^$engine/" | sort -r | while read -r m; do umount -l "$m"; done
      rm -rf "$engine"' _ "$$" "$engine" "$engine_pid" < /dev/null > /dev/null 2>> "$work/watchdog.log" & )
  t0=$SECONDS
  for _ in $(seq 1 60); do
    docker info >/dev/null 2>&1 && break
    kill -0 "$engine_pid" 2>/dev/null || break
    sleep 0.5
  done
  if ! docker info >/dev/null 2>&1; then
    tail -n 15 "$work/dockerd.log"
    stop_engine
    skip "the Docker engine cannot start on this machine (dockerd log above)"
  fi
  measure "engine start: $((SECONDS - t0)) s (dockerd $(docker version -f '{{.Server.Version}}'))"
fi

# ---- base images, then the image -----------------------------------------------------------------

if ! docker image inspect debian:bookworm debian:bookworm-slim >/dev/null 2>&1; then
  t0=$SECONDS
  made_base=1
  in_background timeout 600 "$root/deploy/make-base-image.sh" || fail "deploy/make-base-image.sh failed"
  measure "base image (debootstrap + import): $((SECONDS - t0)) s"
fi
images_before="$(docker images -aq --no-trunc | sort -u)"

export RTC_IMAGE="$image" RTC_FRAMES="$frames" RTC_FRAMES_DIR="$work/frames" RTC_TOKEN_FILE="$work/token"
export RTC_MIN_WORKERS=$((workers + 1)) RTC_THREADS=1
# deploy/compose.sh runs the containers as you, or as the image's user 10001 when you are root.
if [ "$(id -u)" -eq 0 ]; then container_uid=10001; else container_uid="$(id -u)"; fi
RTC_PORT="$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')"
export RTC_PORT

say "building $image from deploy/Dockerfile (log: $work/build.log)"
t0=$SECONDS
# Each log line gets the seconds since the build began, for the time each step took.
build_image() {
  COMPOSE_TIMEOUT=1800 compose build --force-rm master 2>&1 |
    while IFS= read -r line; do printf '%4d %s\n' $((SECONDS - t0)) "$line"; done > "$work/build.log"
  return "${PIPESTATUS[0]}"
}
in_background build_image || { tail -n 40 "$work/build.log" >&2; fail "compose build failed (log tail above)"; }
measure "image build (compose build, cold: apt + compiling 3 programs): $((SECONDS - t0)) s"
say "slowest build steps:"
awk '$2 == "Step" { if (step != "") printf "  %4d s  %s\n", $1 - start, step; start = $1; step = substr($0, index($0, $5)) }
     END { if (step != "") printf "  %4d s  %s\n", last - start, step } { last = $1 }' "$work/build.log" |
  sort -rn | head -n 4 | cut -c1-120
measure "runtime image size: $(( $(docker image inspect -f '{{.Size}}' "$image") / 1000000 )) MB"
grep -q "legacy builder\|Successfully built" "$work/build.log" || say "note: the build log does not name the legacy builder"

# ---- reference frames ----------------------------------------------------------------------------

mkdir -p "$work/ref"
in_background timeout 120 "$render" --frames "$frames" --out "$work/ref/r_####.png" > "$work/render.log" 2>&1 ||
  { cat "$work/render.log" >&2; fail "rtc-render failed"; }

# ---- up: master + workers, health, one worker from the host ------------------------------------

t_up=$SECONDS
up_start="$(date +%s.%N)"
compose_up=1
# In the foreground, as a user runs it: it returns when every container has stopped, with the
# master's status (checked at the end of the run).
COMPOSE_TIMEOUT=300 compose up --no-build --scale worker="$workers" > "$work/up.log" 2>&1 &
up_pid=$!
master_id=""
for _ in $(seq 1 120); do
  master_id="$(compose ps -q master)"
  [ -z "$master_id" ] || break
  kill -0 "$up_pid" 2>/dev/null || break
  sleep 0.5
done
[ -n "$master_id" ] || { cat "$work/up.log" >&2; fail "compose up made no master container within 60 s"; }
bridge="br-$(docker network inspect -f '{{.Id}}' "${project}_default" | cut -c1-12)"

master_log() { docker logs "$master_id" 2>&1; }
# Not `grep -q`: it exits at the first match, and under pipefail `docker logs` dying of SIGPIPE
# on the lines after it would make a found line read as missing (the later in the log the run
# is, the likelier: this is how the CI run of ecffabb failed with frame 0 in the master's log).
master_says() { master_log | grep -- "$1" > /dev/null; }
wait_until() {  # wait_until SECONDS WHAT COMMAND...
  local limit="$1" what="$2"
  shift 2
  local deadline=$((SECONDS + limit))
  until "$@"; do
    [ "$SECONDS" -lt "$deadline" ] || { master_log | tail -n 30 >&2; fail "timed out after $limit s waiting for $what"; }
    # A master that exited may have logged what we wait for just before (a whole run of short
    # frames can end between two checks), and Docker copies a container's last output into its
    # log after the container shows as stopped: look again for up to 5 s before calling it a
    # failure.
    if [ "$(docker inspect -f '{{.State.Running}}' "$master_id")" != true ]; then
      local tries=50
      until "$@"; do
        tries=$((tries - 1))
        [ "$tries" -gt 0 ] || { master_log | tail -n 30 >&2; fail "the master container exited while waiting for $what"; }
        sleep 0.1
      done
      return 0
    fi
    sleep 0.1
  done
}
elapsed() { python3 -c "import sys; print(f'{float(sys.argv[1]) - float(sys.argv[2]):.1f}')" "$(date +%s.%N)" "$up_start"; }

wait_until 60 "the master to listen" master_says "listening on"
measure "compose up -> master listening: $(elapsed) s"
joined() { [ "$(master_log | grep -c ' joined: ')" -ge "$1" ]; }
wait_until 60 "$workers workers to join" joined "$workers"
measure "compose up -> $workers workers joined: $(elapsed) s"

[ "$(docker port "$master_id" 7878/tcp)" = "127.0.0.1:$RTC_PORT" ] ||
  fail "the master's port 7878 is published as '$(docker port "$master_id" 7878/tcp)', expected 127.0.0.1:$RTC_PORT only"
[ "$(docker exec "$master_id" id -u)" = "$container_uid" ] ||
  fail "the master runs as uid $(docker exec "$master_id" id -u), not $container_uid"
worker_ids="$(compose ps -q worker)"
[ "$(wc -w <<<"$worker_ids")" = "$workers" ] || fail "compose ps lists $(wc -w <<<"$worker_ids") workers, expected $workers"
docker exec "$master_id" rtc-healthcheck || fail "rtc-healthcheck in the master says unhealthy"
for id in $worker_ids; do docker exec "$id" rtc-healthcheck || fail "rtc-healthcheck in worker $id says unhealthy"; done
# The image's HEALTHCHECK (every 10 s) reports what rtc-healthcheck says.
healthy() {
  local id
  for id in $master_id $worker_ids; do
    [ "$(docker inspect -f '{{.State.Health.Status}}' "$id")" = healthy ] || return 1
  done
}
wait_until 40 "Docker to report the master and the workers healthy" healthy
measure "compose up -> healthy (first HEALTHCHECK run): $(elapsed) s"

"$worker" --connect "127.0.0.1:$RTC_PORT" --token-file "$RTC_TOKEN_FILE" --threads 1 --name host-worker \
  --retry-seconds 20 > "$work/host-worker.log" 2>&1 &
host_worker_pid=$!
wait_until 60 "the first frame" master_says "frame $first \[seq 0\]"
measure "compose up -> first frame (after the host worker joined): $(elapsed) s"

# ---- the run ends by itself: master exits 0, workers follow the Goodbye ------------------------

in_background timeout 180 docker wait "$master_id" > "$work/master.status" ||
  { master_log | tail -n 30 >&2; fail "the master did not finish within 180 s"; }
code="$(cat "$work/master.status")"
master_log > "$work/master.log"
[ "$code" = 0 ] || { tail -n 30 "$work/master.log" >&2; fail "the master exited with status $code"; }
for id in $worker_ids; do
  code="$(timeout 30 docker wait "$id")" || fail "worker $id did not exit within 30 s of the master"
  [ "$code" = 0 ] || { docker logs "$id" 2>&1 | tail -n 20 >&2; fail "worker $id exited with status $code"; }
done
wait "$host_worker_pid" || { cat "$work/host-worker.log" >&2; fail "the host worker exited with status $?"; }
host_worker_pid=""
up_status=0
wait "$up_pid" || up_status=$?
[ "$up_status" = 0 ] || { tail -n 20 "$work/up.log" >&2; fail "compose.sh up exited with status $up_status after a run that succeeded"; }
grep -q "compose: the master (.*) exited with status 0; frames and stats.jsonl are in $work/frames$" "$work/up.log" ||
  { tail -n 20 "$work/up.log" >&2; fail "compose.sh up did not report the master's status 0"; }
grep -q "said goodbye" "$work/host-worker.log" || { cat "$work/host-worker.log" >&2; fail "the host worker did not get the master's Goodbye"; }
grep -q "worker w[0-9]* (host-worker " "$work/master.log" || fail "the master's log does not show host-worker joining"
compose logs --no-color > "$work/compose.log" 2>&1 || true
grep "frame [0-9]* \[seq" "$work/master.log" | sed 's/^/  /'

# ---- frames on the host equal rtc-render's ------------------------------------------------------

pixels() {  # size, channels and SHA-1 of the pixels, as oiiotool reports them
  "$oiiotool" --info -v --hash "$1" | grep -E '^\S.* : |channel list|SHA-1' | sed 's/^[^:]*: *//'
}
for n in $(seq "$first" "$last"); do
  got="$work/frames/$(printf 'default_%04d.png' "$n")"
  want="$work/ref/$(printf 'r_%04d.png' "$n")"
  [ -f "$got" ] || fail "frame $n is missing on the host: $got"
  [ "$(stat -c %u "$got")" = "$container_uid" ] || fail "$got is owned by uid $(stat -c %u "$got"), expected $container_uid"
  a="$(pixels "$got")" b="$(pixels "$want")"
  [ -n "$a" ] && [ "$a" = "$b" ] && continue
  fail "frame $n differs from rtc-render's:
  compose:    $a
  rtc-render: $b"
done
say "frames $frames on the host equal rtc-render's bit for bit"
python3 - "$work/frames/stats.jsonl" "$first" "$last" <<'EOF' || fail "stats.jsonl on the host is not as expected"
import json, sys
records = [json.loads(line) for line in open(sys.argv[1]) if line.strip()]
frames = sorted(r["frame"] for r in records if r["type"] == "frame")
want = list(range(int(sys.argv[2]), int(sys.argv[3]) + 1))
assert frames == want, f"frames {frames}, expected {want}"
assert records[-1]["type"] == "summary", "no summary line"
print(f"stats.jsonl: {len(frames)} frames, median {records[-1]['median_fps']:.2f} fps, share {records[-1]['worker_share']}")
EOF

# ---- down --------------------------------------------------------------------------------------

t0=$SECONDS
compose down --volumes --remove-orphans --timeout 10 > "$work/down.log" 2>&1 || { cat "$work/down.log" >&2; fail "compose down failed"; }
compose_up=0
measure "compose down: $((SECONDS - t0)) s"
[ -z "$(docker ps -aq --filter "label=com.docker.compose.project=$project")" ] || fail "containers left after down"
! docker network inspect "${project}_default" >/dev/null 2>&1 || fail "network ${project}_default left after down"
say "up -> done: $((SECONDS - t_up)) s"

# ---- failed runs: compose.sh up exits with the master's status, or 1, and names what failed ----
expect_in() {  # expect_in LOG WHAT PATTERN...
  local log="$1" what="$2" pattern
  shift 2
  for pattern in "$@"; do
    grep -q -- "$pattern" "$log" || { cat "$log" >&2; fail "compose.sh up $what: no line matching /$pattern/ (its output above)"; }
  done
}
# A master that refuses its frames (exit 1): the workers never start.
t0=$SECONDS
compose_up=1
up_status=0
RTC_FRAMES=5-2 COMPOSE_TIMEOUT=120 compose up --no-build --scale worker=1 > "$work/up-master-fails.log" 2>&1 || up_status=$?
[ "$up_status" = 1 ] || { cat "$work/up-master-fails.log" >&2; fail "compose.sh up exited with status $up_status when the master failed with 1"; }
expect_in "$work/up-master-fails.log" "with a failing master" \
  "compose: the master (.*) exited with status 1; the end of its log:" "rtc-master: error: --frames: 5-2 is an empty range"
measure "compose.sh up with a failing master: exit $up_status in $((SECONDS - t0)) s"
# A worker that refuses its options (exit 2, through a second compose file); once it has exited,
# the host worker renders the frame (the workers start once the master is healthy, so the master
# must still be running then): the master exits 0, the run 1.
printf 'services:\n  worker:\n    command: ["rtc-worker", "--connect", "master:7878", "--threads", "0"]\n' > "$work/failing.yml"
t0=$SECONDS
compose down --remove-orphans --timeout 10 > "$work/down.log" 2>&1 || { cat "$work/down.log" >&2; fail "compose down failed"; }
up_status=0
RTC_FRAMES=0-0 RTC_MIN_WORKERS=1 COMPOSE_TIMEOUT=120 compose -f "$work/failing.yml" up --no-build --scale worker=1 \
  > "$work/up-worker-fails.log" 2>&1 &
up_pid=$!
worker_exited() {
  local id
  id="$(compose -f "$work/failing.yml" ps -q worker)"
  [ -n "$id" ] && [ "$(docker inspect -f '{{.State.Status}}' "$id")" = exited ]
}
for _ in $(seq 1 120); do
  worker_exited && break
  kill -0 "$up_pid" 2>/dev/null || { cat "$work/up-worker-fails.log" >&2; fail "compose.sh up ended before its worker exited"; }
  sleep 0.5
done
worker_exited || { cat "$work/up-worker-fails.log" >&2; fail "the failing worker did not exit within 60 s"; }
"$worker" --connect "127.0.0.1:$RTC_PORT" --token-file "$RTC_TOKEN_FILE" --threads 1 --name host-worker \
  --retry-seconds 60 > "$work/host-worker-2.log" 2>&1 &
host_worker_pid=$!
wait "$host_worker_pid" || { cat "$work/host-worker-2.log" >&2; fail "the host worker exited with status $? in the run with a failing worker"; }
host_worker_pid=""
wait "$up_pid" || up_status=$?
[ "$up_status" = 1 ] || { cat "$work/up-worker-fails.log" >&2; fail "compose.sh up exited with status $up_status when a worker failed with 2"; }
expect_in "$work/up-worker-fails.log" "with a failing worker" "compose: the master (.*) exited with status 0" \
  "compose: worker .* exited with status 2; the end of its log:" "rtc-worker: error: --threads: Value 0 not in range"
measure "compose.sh up with a failing worker: exit $up_status in $((SECONDS - t0)) s"
compose down --volumes --remove-orphans --timeout 10 > "$work/down.log" 2>&1 || { cat "$work/down.log" >&2; fail "compose down failed"; }
compose_up=0
say "ok (all: $((SECONDS - t_up)) s)"
