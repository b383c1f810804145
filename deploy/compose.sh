#!/usr/bin/env bash
# Docker Compose on deploy/docker-compose.yml with what the file needs made first: the frames
# folder and a random token (made once, mode 600), both owned by the user the containers run as
# (yours; the image's rtc user 10001 when you are root). Runs `docker compose` (v2) when present,
# else `docker-compose` (v1), with your arguments. `up` in the foreground then exits with the
# master's status (compose's own says nothing of it), naming the master or a worker that failed:
# 0 after a whole run, the master's status when it failed, else compose's own when it failed, else
# 1 when a worker did; 130 or 143 after a Ctrl-C or SIGTERM.
# Usage: ./deploy/compose.sh up --build --scale worker=3     # frames: out/compose/default_####.png
#        ./deploy/compose.sh logs master;  ./deploy/compose.sh down
#        ./deploy/compose.sh --help                          # this text; compose's own: help
# Env: RTC_FRAMES_DIR (out/compose), RTC_TOKEN_FILE (out/compose-token), RTC_UID/RTC_GID (yours;
# 10001, the image's rtc user, when you are root), and the other settings listed at the top of
# deploy/docker-compose.yml.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"

# Before anything is made: the header above, without its '# '.
if [ $# -eq 1 ] && { [ "$1" = --help ] || [ "$1" = -h ]; }; then
  sed -n '2,/^set -euo/{/^set -euo/d;s/^# \{0,1\}//;p}' "$0"
  exit 0
fi

if docker compose version >/dev/null 2>&1; then
  compose=(docker compose)
elif command -v docker-compose >/dev/null 2>&1; then
  compose=(docker-compose)
else
  echo "compose: neither 'docker compose' nor 'docker-compose' is installed (./deploy/install-deps.sh installs docker-compose)" >&2
  exit 1
fi

if [ "$(id -u)" -eq 0 ]; then
  # Root on the host: the containers still run as the image's unprivileged user.
  export RTC_UID="${RTC_UID:-10001}" RTC_GID="${RTC_GID:-10001}"
else
  RTC_UID="${RTC_UID:-$(id -u)}" RTC_GID="${RTC_GID:-$(id -g)}"
  export RTC_UID RTC_GID
fi
frames_dir="$(realpath -m "${RTC_FRAMES_DIR:-$root/out/compose}")"
token_file="$(realpath -m "${RTC_TOKEN_FILE:-$root/out/compose-token}")"
export RTC_FRAMES_DIR="$frames_dir" RTC_TOKEN_FILE="$token_file"

mkdir -p "$frames_dir" "$(dirname "$token_file")"
if [ ! -s "$token_file" ]; then
  (umask 077 && head -c 32 /dev/urandom | od -An -tx1 | tr -d ' \n' > "$token_file")
  echo "compose: made a random token in $token_file (workers elsewhere need it: rtc-worker --token-file)"
fi
if [ "$(id -u)" -eq 0 ]; then
  chown "$RTC_UID:$RTC_GID" "$frames_dir" "$token_file"
elif [ "$(stat -c %u "$frames_dir")" != "$RTC_UID" ] && [ ! -w "$frames_dir" ]; then
  echo "compose: $frames_dir is not writable by uid $RTC_UID, the containers' user" >&2
  exit 1
fi

compose+=(-f "$root/deploy/docker-compose.yml")

# `up` in the foreground (no -d) returns when every container has stopped, with a status that
# says nothing of theirs (docker-compose v1 exits 0 when the master failed). Every other command
# is compose's alone.
globals=() foreground_up=0
for ((i = 1; i <= $#; i++)); do
  if [ "${!i}" = up ]; then
    foreground_up=1
    for arg in "${@:i+1}"; do
      case "$arg" in
        -d|--detach|-[!-]*d*|--exit-code-from|--exit-code-from=*|--abort-on-container-exit|--no-start|-h|--help)
          foreground_up=0 ;;
      esac
    done
    break
  fi
  globals+=("${!i}")
done
[ "$foreground_up" = 1 ] || exec "${compose[@]}" "$@"

# Compose runs in a session of its own: a Ctrl-C or a SIGTERM reaches it once, from here (it stops
# the containers; the master finishes the frames in flight), and a second one forces it, as
# compose's own message says.
signalled=""
forward() {
  signalled="$1"
  kill -s "$1" "$compose_pid" 2>/dev/null || true
}
trap 'forward INT' INT
trap 'forward TERM' TERM
setsid "${compose[@]}" "$@" &
compose_pid=$!
# (A trapped signal ends `wait` early: wait again while compose runs.)
while :; do
  status=0
  wait "$compose_pid" || status=$?
  kill -0 "$compose_pid" 2>/dev/null || break
done
trap - INT TERM

# Then each container's own status: the master's is the run's, and a worker that failed is named.
# (not one-off containers of `compose.sh run`)
exit_of() {
  docker inspect -f '{{index .Config.Labels "com.docker.compose.oneoff"}} {{.State.Status}} {{.State.ExitCode}} {{.Name}}' "$1" 2>/dev/null |
    grep -iv '^true ' | cut -d' ' -f2- || true
}
log_tail() { docker logs --tail 6 "$1" 2>&1 | sed 's/^/  /' >&2 || true; }
stopped() { [ "$1" = exited ] || [ "$1" = dead ]; }
master_status=0 worker_failed=0 master_seen=0
for id in $("${compose[@]}" "${globals[@]}" ps -a -q master 2>/dev/null || true); do
  read -r state code name <<<"$(exit_of "$id")"
  [ -n "${state:-}" ] || continue
  master_seen=1
  name="${name#/}"
  if ! stopped "$state"; then
    echo "compose: the master ($name) is $state" >&2
  elif [ -n "$signalled" ] && { [ "$code" = 130 ] || [ "$code" = 143 ]; }; then
    # Compose stopped it (SIGTERM): a run cut short, not a failure.
    echo "compose: the master ($name) stopped before the run's end (status $code); the frames it finished are in $frames_dir"
  elif [ "$code" != 0 ]; then
    echo "compose: the master ($name) exited with status $code; the end of its log:" >&2
    log_tail "$id"
    master_status="$code"
  else
    echo "compose: the master ($name) exited with status 0; frames and stats.jsonl are in $frames_dir"
  fi
done
for id in $("${compose[@]}" "${globals[@]}" ps -a -q worker 2>/dev/null || true); do
  read -r state code name <<<"$(exit_of "$id")"
  if stopped "${state:-}" && [ "$code" != 0 ]; then
    echo "compose: worker ${name#/} exited with status $code; the end of its log:" >&2
    log_tail "$id"
    worker_failed=1
  fi
done
[ "$master_seen" = 1 ] || { echo "compose: no master container was made" >&2; [ "$status" != 0 ] || status=1; }
# The status: a signal's (130, 143), else the master's when it failed, else compose's own when it
# failed, else 1 when a worker failed.
if [ -n "$signalled" ]; then
  echo "compose: stopped by SIG$signalled" >&2
  [ "$signalled" = INT ] && exit 130
  exit 143
fi
[ "$master_status" = 0 ] || exit "$master_status"
[ "$status" = 0 ] || exit "$status"
exit "$worker_failed"
