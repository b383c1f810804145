// The time stamp counter, for code that times itself in ticks (ShadowOrderChooser, the
// trace-call tally). Not compiled per ISA: every x86-64 has it.
#pragma once

#include <cstdint>

#include <x86intrin.h>

namespace rtc {

/// The time stamp counter (rdtsc; not serialising).
[[nodiscard]] inline std::uint64_t read_tsc() { return __rdtsc(); }

}  // namespace rtc
