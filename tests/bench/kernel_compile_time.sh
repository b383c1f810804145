#!/usr/bin/env bash
# CPU seconds (user + sys) to compile common/render/render_kernels.cpp once per ISA, as the
# build does it but with ccache bypassed, REPEAT times: the compile-time cost of the kernel
# instantiations (render_kernels.cpp's kCompiled). Needs a configured build folder.
# Usage: tests/bench/kernel_compile_time.sh [BUILD_DIR] [REPEAT]
set -euo pipefail
build=${1:-build/release}
repeat=${2:-3}
cd "$build"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for r in $(seq 1 "$repeat"); do
  total=0
  line="run $r:"
  for obj in $(ninja -t targets all | grep -o 'common/render/CMakeFiles/rtc_render_isa_[a-z0-9]*\.dir/render_kernels\.cpp\.o' | sort -u); do
    isa=$(echo "$obj" | sed 's/.*rtc_render_isa_\([a-z0-9]*\)\.dir.*/\1/')
    cmd=$(ninja -t commands "$obj" | tail -1 | sed -e 's#^[^ ]*ccache ##' -e "s# -o [^ ]*# -o $tmp/$isa.o#" \
          -e 's# -MD -MT [^ ]* -MF [^ ]*##')
    s=$( { /usr/bin/time -f "%U %S" bash -c "$cmd" >/dev/null; } 2>&1 | tail -1 | awk '{print $1 + $2}')
    line="$line $isa ${s}s"
    total=$(echo "$total + $s" | bc)
  done
  echo "$line; total ${total}s"
done
