#!/usr/bin/env bash
# Installs the Debian 12 packages rtc builds, tests and benchmarks with; safe to run again.
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config ccache git
  libopenimageio-dev openimageio-tools libopenexr-dev libimath-dev
  libglm-dev libtbb-dev libspdlog-dev libfmt-dev libcli11-dev nlohmann-json3-dev
  libassimp-dev libtinyobjloader-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libasio-dev liblz4-dev libzstd-dev libssl-dev zlib1g-dev iproute2 iperf3
  libembree-dev python3 gnuplot-nox
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed'; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages already installed"
  exit 0
fi

echo "install-deps: installing ${#missing[@]} missing packages: ${missing[*]}"
sudo_cmd=()
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null 2>&1 || { echo "install-deps: need root or sudo to install: ${missing[*]}" >&2; exit 1; }
  sudo_cmd=(sudo)
fi
export DEBIAN_FRONTEND=noninteractive
"${sudo_cmd[@]}" apt-get update -qq
"${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
echo "install-deps: done"
