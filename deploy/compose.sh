#!/usr/bin/env bash
# Docker Compose on deploy/docker-compose.yml with what the file needs made first: the frames
# folder and a random token (made once, mode 600), both owned by the user the containers run as
# (yours; the image's rtc user 10001 when you are root). Runs `docker compose` (v2) when present,
# else `docker-compose` (v1), with your arguments.
# Usage: ./deploy/compose.sh up --build --scale worker=3     # frames: out/compose/default_####.png
#        ./deploy/compose.sh logs master;  ./deploy/compose.sh down
# Env: RTC_FRAMES_DIR (out/compose), RTC_TOKEN_FILE (out/compose-token), and the settings listed
# at the top of deploy/docker-compose.yml.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"

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

exec "${compose[@]}" -f "$root/deploy/docker-compose.yml" "$@"
