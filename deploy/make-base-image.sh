#!/usr/bin/env bash
# Makes the Debian 12 base images deploy/Dockerfile builds FROM, for machines that reach no image
# registry: debootstrap (minbase) from Debian's apt repository, trimmed like Docker Hub's slim
# image, imported as debian:bookworm and tagged debian:bookworm-slim. With Docker Hub access this
# is not needed: `docker build` pulls the real images of the same names.
# Usage: ./deploy/make-base-image.sh [--force]     (root; a running Docker engine; debootstrap)
#   --force   remake the images even when both names exist
# Env: RTC_DEBIAN_MIRROR (default http://deb.debian.org/debian), RTC_DEBIAN_SECURITY_MIRROR
#      (the image's bookworm-security source; default http://deb.debian.org/debian-security)
set -euo pipefail

force=0
for arg in "$@"; do
  case "$arg" in
    --force) force=1 ;;
    -h|--help) sed -n '2,9p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "make-base-image: unknown option \"$arg\" (see --help)" >&2; exit 2 ;;
  esac
done
mirror="${RTC_DEBIAN_MIRROR:-http://deb.debian.org/debian}"
security_mirror="${RTC_DEBIAN_SECURITY_MIRROR:-http://deb.debian.org/debian-security}"
images=(debian:bookworm debian:bookworm-slim)

docker info >/dev/null 2>&1 || { echo "make-base-image: no Docker engine answers (docker info failed); start dockerd first" >&2; exit 1; }
if [ "$force" = 0 ] && docker image inspect "${images[@]}" >/dev/null 2>&1; then
  echo "make-base-image: ${images[*]} already exist (--force remakes them)"
  exit 0
fi
[ "$(id -u)" -eq 0 ] || { echo "make-base-image: debootstrap needs root" >&2; exit 1; }
command -v debootstrap >/dev/null 2>&1 || { echo "make-base-image: debootstrap is not installed (./deploy/install-deps.sh installs it)" >&2; exit 1; }

work="$(mktemp -d "${TMPDIR:-/tmp}/rtc-base.XXXXXX")"
# --one-file-system: never into a mount debootstrap may have left behind (proc, sys).
trap 'rm -rf --one-file-system "$work"' EXIT
root="$work/rootfs"
start=$SECONDS
echo "make-base-image: debootstrap --variant=minbase bookworm from $mirror"
if ! debootstrap --variant=minbase bookworm "$root" "$mirror" > "$work/debootstrap.log" 2>&1; then
  tail -n 20 "$work/debootstrap.log" >&2
  echo "make-base-image: debootstrap failed (log above)" >&2
  exit 1
fi

# What Docker Hub's debian images (debuerreotype) do: the same apt sources, no apt caches or
# lists, and for the slim image no documentation, manuals or translations (also for packages
# installed later: the dpkg excludes stay in the image).
rm -f "$root/etc/apt/sources.list"
cat > "$root/etc/apt/sources.list.d/debian.sources" <<SOURCES
Types: deb
URIs: $mirror
Suites: bookworm bookworm-updates
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg

Types: deb
URIs: $security_mirror
Suites: bookworm-security
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg
SOURCES
cat > "$root/etc/dpkg/dpkg.cfg.d/docker" <<'DPKG'
path-exclude /usr/share/doc/*
path-include /usr/share/doc/*/copyright
path-exclude /usr/share/man/*
path-exclude /usr/share/groff/*
path-exclude /usr/share/info/*
path-exclude /usr/share/lintian/*
path-exclude /usr/share/linda/*
path-exclude /usr/share/locale/*
path-include /usr/share/locale/locale.alias
DPKG
cat > "$root/etc/apt/apt.conf.d/docker-clean" <<'APT'
DPkg::Post-Invoke { "rm -f /var/cache/apt/archives/*.deb /var/cache/apt/archives/partial/*.deb /var/cache/apt/*.bin || true"; };
APT::Update::Post-Invoke { "rm -f /var/cache/apt/archives/*.deb /var/cache/apt/archives/partial/*.deb /var/cache/apt/*.bin || true"; };
Dir::Cache::pkgcache ""; Dir::Cache::srcpkgcache "";
APT
echo 'Acquire::Languages "none";' > "$root/etc/apt/apt.conf.d/docker-no-languages"
find "$root/usr/share/doc" -mindepth 2 ! -name copyright ! -type d -delete
find "$root/usr/share/doc" -mindepth 1 -type d -empty -delete
rm -rf "$root"/usr/share/{man,groff,info,lintian,linda}/* "$root"/var/lib/apt/lists/* "$root"/var/cache/apt/* \
       "$root"/var/log/* "$root"/tmp/* "$root"/var/cache/debconf/*-old
find "$root/usr/share/locale" -mindepth 1 -maxdepth 1 ! -name locale.alias -exec rm -rf {} +
: > "$root/etc/resolv.conf"
echo localhost > "$root/etc/hostname"

tar --numeric-owner -C "$root" -c . | docker import --change 'CMD ["bash"]' \
  --message "rtc make-base-image: debootstrap minbase bookworm" - "${images[0]}" >/dev/null
docker tag "${images[0]}" "${images[1]}"
size=$(docker image inspect -f '{{.Size}}' "${images[0]}")
echo "make-base-image: made ${images[*]} ($((size / 1000000)) MB) in $((SECONDS - start)) s"
