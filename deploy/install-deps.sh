#!/usr/bin/env bash
# Installs the Debian 12 packages rtc builds, tests and benchmarks with; safe to run again.
# Usage: ./deploy/install-deps.sh [--build-only]
#   --build-only  only what building rtc-master, rtc-worker and rtc-render needs (the build stage
#                 of deploy/Dockerfile): no test, benchmark or deployment-test tools
set -euo pipefail

build_only=0
for arg in "$@"; do
  case "$arg" in
    --build-only) build_only=1 ;;
    -h|--help) sed -n '2,5p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "install-deps: unknown option \"$arg\" (see --help)" >&2; exit 2 ;;
  esac
done

# What building the three programs needs (CMakeLists.txt's find_package list). openimageio-tools
# too: Debian's OpenImageIOTargets.cmake fails find_package when its programs (iconvert, ...) are absent.
packages=(
  build-essential cmake ninja-build pkg-config
  libopenimageio-dev openimageio-tools libopenexr-dev libimath-dev
  libglm-dev libtbb-dev libspdlog-dev libfmt-dev libcli11-dev nlohmann-json3-dev
  libtinygltf-dev libtinyobjloader-dev
  libasio-dev liblz4-dev libzstd-dev libssl-dev zlib1g-dev
)
if [ "$build_only" = 0 ]; then
  packages+=(
    ccache git
    libgtest-dev libgmock-dev libbenchmark-dev libembree-dev
    # tests/fuzz: libFuzzer targets (clang with its runtime); scene_load_timing compares Assimp
    clang-14 libclang-rt-14-dev libassimp-dev
    iproute2 iperf3 python3 gnuplot-nox
    # Commands the tests and benchmarks call: Cluster.tls makes certificates (openssl),
    # compose_test.sh lists processes (ps), kernel_compile_time.sh times and sums (/usr/bin/time, bc)
    openssl procps time bc
    # tests/deploy: compose v1, a base image made without a registry (debootstrap + docker import)
    docker-compose debootstrap
  )
  # ... and a Docker engine started by hand (no systemd): Debian's, unless an engine (dockerd) is
  # installed already (Docker's own docker-ce and containerd.io conflict with Debian's containerd
  # and runc, and installing those would remove them). A docker client alone is not an engine:
  # these machines' images carry one in /usr/local/bin.
  command -v dockerd >/dev/null 2>&1 || packages+=(docker.io containerd runc)
fi

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed'; then
    missing+=("$p")
  fi
done
if [ "$build_only" = 0 ]; then
  # The Kubernetes manifest check needs kubectl (for `kubectl kustomize`) and npm (for the
  # kubernetes-models schemas). Machines may carry newer ones from elsewhere; only when the command
  # is absent do we fall back to Debian's packages (kubectl 1.20 with kustomize v2, npm 9).
  command -v kubectl >/dev/null 2>&1 || missing+=(kubernetes-client)
  command -v npm >/dev/null 2>&1 || missing+=(npm)
fi

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
# Through env: sudo's env_reset would drop an exported DEBIAN_FRONTEND (iperf3 asks a question).
"${sudo_cmd[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -qq
"${sudo_cmd[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}"
echo "install-deps: done"
