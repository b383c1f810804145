// Opens and closes the region in which a kernel source's rtc::isa_<name> code is compiled for
// its ISA. Kernel sources are compiled without -m flags; only functions defined between
// RTC_ISA_BEGIN and RTC_ISA_END get the ISA (RTC_ISA_TARGET, set per ISA by
// cmake/rtc_isa.cmake). Every other header must be included before RTC_ISA_BEGIN, so that the
// out-of-line copies of inline std::, glm:: and rtc:: functions a kernel source emits stay
// baseline x86-64 and can never be picked by the linker for ordinary callers on a CPU without
// the ISA (STYLE.md; tests/isa/check_isa_leak.sh checks the objects).
#pragma once

#ifndef RTC_ISA_TARGET
#error "RTC_ISA_TARGET is set by rtc_isa_kernels() in cmake/rtc_isa.cmake"
#endif

#define RTC_PRAGMA(x) _Pragma(#x)
#if defined(__clang__)
#define RTC_ISA_PRAGMA_PUSH(t) RTC_PRAGMA(clang attribute push(__attribute__((target(t))), apply_to = function))
#define RTC_ISA_BEGIN RTC_ISA_PRAGMA_PUSH(RTC_ISA_TARGET)
#define RTC_ISA_END RTC_PRAGMA(clang attribute pop)
#else
#define RTC_ISA_PRAGMA_TARGET(t) RTC_PRAGMA(GCC target(t))
#define RTC_ISA_BEGIN RTC_PRAGMA(GCC push_options) RTC_ISA_PRAGMA_TARGET(RTC_ISA_TARGET)
#define RTC_ISA_END RTC_PRAGMA(GCC pop_options)
#endif
