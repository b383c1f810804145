#!/usr/bin/env bash
# Fails when a kernel object file holds a function outside the rtc::isa_<name> namespaces that
# uses instructions beyond baseline x86-64 (SSE2): such a copy of an inline function (std::,
# glm::, rtc:: helpers) could be picked by the linker for ordinary callers and crash on a CPU
# without that ISA (STYLE.md: nothing outside those namespaces gets ISA flags).
# Usage: check_isa_leak.sh OBJECT...
set -euo pipefail
# SSE3/SSSE3/SSE4.1/SSE4.2/POPCNT/AVX and later: any of these mnemonics, or any VEX/EVEX
# encoded instruction (mnemonics starting with v), is beyond baseline.
pattern='^[[:space:]]*[0-9a-f]+:[[:space:]]+(blendv?p[sd]|pblend[vw]b?|ptest|pcmpeqq|pcmpgtq|pmin[su][bdw]|pmax[su][bdw]|pmulld|round[ps][sd]|insertps|extractps|pextr[bdq]|pinsr[bdq]|dpp[sd]|popcnt|crc32|lzcnt|tzcnt|movddup|movs[hl]dup|hadd|hsub|pshufb|palignr|pabs[bdw]|pmovsx|pmovzx|packusdw|v[a-z0-9]+)[[:space:]]'
status=0
for obj in "$@"; do
  bad=$(objdump -d --no-show-raw-insn -C "$obj" | awk -v pat="$pattern" '
    /^[0-9a-f]+ <.*>:$/ { fn = $0; next }
    fn != "" && $0 ~ pat && fn !~ /isa_(sse42|avx2|avx512)::/ { print fn; fn = "" }')
  if [ -n "$bad" ]; then
    echo "check_isa_leak: $obj: functions outside rtc::isa_* compiled with ISA instructions:" >&2
    echo "$bad" | sort -u | head -20 >&2
    status=1
  fi
done
[ $status -eq 0 ] && echo "check_isa_leak: $# kernel objects clean"
exit $status
