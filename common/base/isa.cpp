// ISA names and CPU detection (GCC's __builtin_cpu_supports reads CPUID and XCR0).
#include "common/base/isa.h"

#include "common/base/error.h"

namespace rtc {

std::string_view isa_name(Isa isa) {
  switch (isa) {
    case Isa::Sse42:
      return "sse4.2";
    case Isa::Avx2:
      return "avx2";
    case Isa::Avx512:
      return "avx512";
  }
  return "unknown";
}

int isa_packet_width(Isa isa) {
  switch (isa) {
    case Isa::Sse42:
      return 4;
    case Isa::Avx2:
      return 8;
    case Isa::Avx512:
      return 16;
  }
  return 4;
}

std::string isa_packet_description(Isa isa) {
  const int w = isa_packet_width(isa);
  const int bw = packet_block_width(w);
  return std::to_string(w) + "-wide packets (" + std::to_string(bw) + "x" + std::to_string(w / bw) + " pixels)";
}

Isa parse_isa(std::string_view name) {
  if (name == "sse4" || name == "sse42" || name == "sse4.2") return Isa::Sse42;
  if (name == "avx2") return Isa::Avx2;
  if (name == "avx512") return Isa::Avx512;
  throw Error("unknown ISA \"" + std::string(name) + "\" (expected sse4, avx2 or avx512)");
}

bool cpu_supports(Isa isa) {
  __builtin_cpu_init();
  switch (isa) {
    case Isa::Sse42:
      return __builtin_cpu_supports("sse4.2") && __builtin_cpu_supports("popcnt");
    case Isa::Avx2:
      return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") &&
             __builtin_cpu_supports("bmi") && __builtin_cpu_supports("bmi2") && __builtin_cpu_supports("popcnt");
    case Isa::Avx512:
      return cpu_supports(Isa::Avx2) && __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq") &&
             __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512vl");
  }
  return false;
}

void require_cpu_support(Isa isa) {
  if (!cpu_supports(isa)) throw Error("this CPU does not support " + std::string(isa_name(isa)));
}

void throw_isa_not_compiled(Isa isa) {
  throw Error("ISA " + std::string(isa_name(isa)) + " is not compiled into this build (RTC_ISAS)");
}

std::vector<Isa> compiled_isas() {
  std::vector<Isa> out;
#ifdef RTC_HAVE_ISA_SSE42
  out.push_back(Isa::Sse42);
#endif
#ifdef RTC_HAVE_ISA_AVX2
  out.push_back(Isa::Avx2);
#endif
#ifdef RTC_HAVE_ISA_AVX512
  out.push_back(Isa::Avx512);
#endif
  return out;
}

Isa best_isa() {
  const std::vector<Isa> isas = compiled_isas();
  for (auto it = isas.rbegin(); it != isas.rend(); ++it) {
    if (cpu_supports(*it)) return *it;
  }
  throw Error("this CPU lacks SSE4.2 and POPCNT, the least rtc's kernels need");
}

}  // namespace rtc
