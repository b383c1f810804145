#!/usr/bin/env bash
# Collects the shared libraries the given programs load (ldd's closure) that the runtime base
# image lacks, for deploy/Dockerfile's runtime stage: only these files, not their Debian packages,
# whose dependencies would add what the programs never load (Mesa and LLVM through libglx0: an
# image of 731 MB against 445). Each library's package copyright file goes with it, and a
# manifest lists library, package and version.
# Usage: deploy/runtime-libs.sh BASE_PACKAGES OUT_DIR PROGRAM_OR_LIBRARY...
#   PROGRAM_OR_LIBRARY  a program, or a library it loads with dlopen (taken with its own closure)
#   BASE_PACKAGES  file listing the runtime base's installed packages, one a line: their
#                  libraries are not copied (the base has them)
#   OUT_DIR        receives lib/rtc/*.so*, share/doc/PACKAGE/copyright, share/rtc/runtime-libraries.txt
set -euo pipefail
[ $# -ge 3 ] || { echo "runtime-libs: usage: $0 BASE_PACKAGES OUT_DIR PROGRAM_OR_LIBRARY..." >&2; exit 2; }
base_packages="$1"
out="$2"
shift 2
[ -r "$base_packages" ] || { echo "runtime-libs: cannot read $base_packages" >&2; exit 1; }

mkdir -p "$out/lib/rtc" "$out/share/rtc"
manifest="$out/share/rtc/runtime-libraries.txt"

# Every library the programs load, once.
paths=()
for program in "$@"; do
  [ -f "$program" ] || { echo "runtime-libs: $program does not exist" >&2; exit 1; }
  libs="$(ldd "$program")" || { echo "runtime-libs: ldd $program failed" >&2; exit 1; }
  if grep -q 'not found' <<<"$libs"; then
    echo "runtime-libs: $program needs libraries ldd cannot find:" >&2
    grep 'not found' <<<"$libs" >&2
    exit 1
  fi
  case "$program" in *.so|*.so.*) paths+=("$program") ;; esac
  mapfile -t -O "${#paths[@]}" paths < <(awk '$2 == "=>" && $3 ~ /^\// { print $3 } $1 ~ /^\// { print $1 }' <<<"$libs")
done
mapfile -t paths < <(printf '%s\n' "${paths[@]}" | sort -u)

# Their packages, in one dpkg query. dpkg knows a file by the path its package installed; with
# the merged /usr, ldd and readlink may give the other spelling (/lib vs /usr/lib).
spellings() {
  local real
  real="$(readlink -f "$1")"
  printf '%s\n' "$1" "${1#/usr}" "/usr$1" "$real" "${real#/usr}" "/usr$real"
}
declare -A owner_of=()
while IFS= read -r line; do
  case "$line" in diversion*) continue ;; esac
  package="${line%%: *}"
  owner_of["${line#*: }"]="${package%%[:,]*}"
done < <(for p in "${paths[@]}"; do spellings "$p"; done | sort -u | xargs -d '\n' dpkg-query -S 2>/dev/null || true)

: > "$manifest"
copied=0
skipped=0
for path in "${paths[@]}"; do
  package=""
  while read -r spelling; do
    package="${owner_of[$spelling]:-}"
    [ -z "$package" ] || break
  done < <(spellings "$path")
  [ -n "$package" ] || { echo "runtime-libs: no Debian package owns $path" >&2; exit 1; }
  if grep -qx "$package" "$base_packages"; then
    skipped=$((skipped + 1))
    continue
  fi
  cp -L "$path" "$out/lib/rtc/$(basename "$path")"
  if [ -f "/usr/share/doc/$package/copyright" ] && [ ! -f "$out/share/doc/$package/copyright" ]; then
    mkdir -p "$out/share/doc/$package"
    cp "/usr/share/doc/$package/copyright" "$out/share/doc/$package/copyright"
  fi
  printf '%s %s\n' "$(basename "$path")" "$package" >> "$manifest"
  copied=$((copied + 1))
done
# Package versions, in one query too.
# shellcheck disable=SC2016  # dpkg's format, not the shell's
cut -d' ' -f2 "$manifest" | sort -u | xargs -r dpkg-query -W -f='${Package} ${Version}\n' > "$out/share/rtc/versions.tmp"
awk 'NR == FNR { version[$1] = $2; next } { print $1, $2, version[$2] }' "$out/share/rtc/versions.tmp" "$manifest" |
  sort > "$manifest.tmp"
mv "$manifest.tmp" "$manifest"
rm -f "$out/share/rtc/versions.tmp"
echo "runtime-libs: $copied libraries from $(cut -d' ' -f2 "$manifest" | sort -u | wc -l) packages" \
     "($(du -sm "$out/lib/rtc" | cut -f1) MB); $skipped already in the base image"
