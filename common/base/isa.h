// Instruction-set levels the packet kernels are compiled for, and run-time CPU detection.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace rtc {

/// Kernel ISA levels, lowest first (cmake/rtc_isa.cmake compiles the kernels once for each).
enum class Isa { Sse42 = 0, Avx2 = 1, Avx512 = 2 };

[[nodiscard]] std::string_view isa_name(Isa isa);
/// Rays per packet of that level's kernels: 4 (2x2 pixels), 8 (4x2) or 16 (4x4).
[[nodiscard]] int isa_packet_width(Isa isa);
/// Width in pixels of the block a packet of `packet_width` rays covers: 1 for single rays,
/// 2 for 4 rays (2x2), 4 for 8 (4x2) and 16 (4x4); the height is packet_width / that.
[[nodiscard]] constexpr int packet_block_width(int packet_width) {
  return packet_width >= 8 ? 4 : (packet_width == 4 ? 2 : 1);
}
/// "16-wide packets (4x4 pixels)" and the like, for logs.
[[nodiscard]] std::string isa_packet_description(Isa isa);
/// Parses "sse4"/"sse42"/"sse4.2", "avx2", "avx512"; throws rtc::Error on anything else.
[[nodiscard]] Isa parse_isa(std::string_view name);
/// Whether this CPU can run kernels of that level.
[[nodiscard]] bool cpu_supports(Isa isa);
/// The ISAs compiled into this binary, lowest first.
[[nodiscard]] std::vector<Isa> compiled_isas();
/// Throws rtc::Error unless this CPU can run kernels of that level (per-ISA kernel tables call
/// it before handing out their entry points).
void require_cpu_support(Isa isa);
/// Throws the rtc::Error for a level the kernel tables were not built with (RTC_ISAS).
[[noreturn]] void throw_isa_not_compiled(Isa isa);
/// The best ISA that is both compiled in and supported by this CPU; throws rtc::Error when the
/// CPU lacks even SSE4.2.
[[nodiscard]] Isa best_isa();

}  // namespace rtc
