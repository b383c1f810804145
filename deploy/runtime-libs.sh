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

owner() {
  # dpkg knows a library by the path its package installed; with the merged /usr, ldd and
  # readlink may give the other spelling (/lib vs /usr/lib).
  local p candidates=("$1" "$(readlink -f "$1")")
  for p in "${candidates[@]}"; do
    candidates+=("${p#/usr}" "/usr${p}")
  done
  for p in "${candidates[@]}"; do
    dpkg-query -S "$p" 2>/dev/null | head -n 1 | cut -d: -f1 && return 0
  done
  return 1
}

mkdir -p "$out/lib/rtc" "$out/share/rtc"
manifest="$out/share/rtc/runtime-libraries.txt"
: > "$manifest"
declare -A seen=()
copied=0
skipped=0
for program in "$@"; do
  [ -f "$program" ] || { echo "runtime-libs: $program does not exist" >&2; exit 1; }
  libs="$(ldd "$program")" || { echo "runtime-libs: ldd $program failed" >&2; exit 1; }
  if grep -q 'not found' <<<"$libs"; then
    echo "runtime-libs: $program needs libraries ldd cannot find:" >&2
    grep 'not found' <<<"$libs" >&2
    exit 1
  fi
  while read -r path; do
    [ -n "${seen[$path]:-}" ] && continue
    seen[$path]=1
    package="$(owner "$path")" || { echo "runtime-libs: no Debian package owns $path ($program loads it)" >&2; exit 1; }
    package="${package%%:*}"
    if grep -qx "$package" "$base_packages"; then
      skipped=$((skipped + 1))
      continue
    fi
    cp -L "$path" "$out/lib/rtc/$(basename "$path")"
    if [ -f "/usr/share/doc/$package/copyright" ] && [ ! -f "$out/share/doc/$package/copyright" ]; then
      mkdir -p "$out/share/doc/$package"
      cp "/usr/share/doc/$package/copyright" "$out/share/doc/$package/copyright"
    fi
    printf '%s %s %s\n' "$(basename "$path")" "$package" "$(dpkg-query -W -f='${Version}' "$package")" >> "$manifest"
    copied=$((copied + 1))
  done < <(case "$program" in *.so|*.so.*) echo "$program" ;; esac
           awk '$2 == "=>" && $3 ~ /^\// { print $3 } $1 ~ /^\// { print $1 }' <<<"$libs")
done
sort -o "$manifest" "$manifest"
echo "runtime-libs: $copied libraries from $(cut -d' ' -f2 "$manifest" | sort -u | wc -l) packages" \
     "($(du -sm "$out/lib/rtc" | cut -f1) MB); $skipped already in the base image"
