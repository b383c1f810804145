// Where a frame's tracing time goes: time stamp counter ticks inside the renderer's two trace
// calls (closest hits, occlusion), on rtc's kd-trees and on an external tracer (rtc-bench's
// Embree renderer) alike, by what the call traced: primary rays or mirror rays, or one light's
// shadow rays, and how many of the packet's lanes carry a ray. Compiled into the renderer only
// with the CMake option RTC_TRACE_TICKS (the `ticks` preset): the clock reads cost trace time,
// so a default build times nothing and its tile kernels carry no trace of it. rtc-bench's full
// mode prints the tally beside the Embree renderer's (README, "rtc-bench"). Not compiled per ISA.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "common/simd/tsc.h"

#ifndef RTC_TRACE_TICKS
#define RTC_TRACE_TICKS 0
#endif

namespace rtc {

/// Whether this build's renderer times its trace calls (RTC_TRACE_TICKS).
inline constexpr bool kTraceTicks = RTC_TRACE_TICKS != 0;

/// What a trace call traced: closest hits of primary rays (depth 0) or of mirror rays, or the
/// occlusion of one light's shadow rays.
enum class TraceCall : std::uint8_t { Primary, Mirror, Shadow };

/// How full a call's packet was: every lane, more than half, at most half.
enum class LaneFill : std::uint8_t { Full, MoreThanHalf, AtMostHalf };
inline constexpr int kLaneFills = 3;

/// The fill of a packet of `width` lanes with `rays` rays in it.
[[nodiscard]] constexpr LaneFill lane_fill(unsigned rays, unsigned width) {
  if (rays >= width) return LaneFill::Full;
  return 2 * rays > width ? LaneFill::MoreThanHalf : LaneFill::AtMostHalf;
}

/// Lights are told apart up to this many; the last row sums the lights from index
/// kTraceTickLights - 1 on.
inline constexpr int kTraceTickLights = 8;

/// One row of the tally: calls of one kind and fill on one side.
struct TraceTickRow {
  bool external = false;  ///< traced by the external tracer (else by rtc's kd-trees)
  TraceCall call = TraceCall::Primary;
  int light = -1;  ///< Shadow: the light's index (kTraceTickLights - 1: that one and the rest); else -1
  LaneFill fill = LaneFill::Full;
  std::uint64_t ticks = 0, calls = 0, rays = 0;
};

/// Adds one call's ticks and rays (`light`: Shadow only, any index).
void add_trace_ticks(bool external, TraceCall call, int light, LaneFill fill, std::uint64_t ticks, unsigned rays);

/// The rows with calls, sides and kinds in a fixed order (rtc's before the external tracer's,
/// then primary, mirror, shadow by light, each by fill).
[[nodiscard]] std::vector<TraceTickRow> trace_ticks();

/// Sets every count to zero.
void reset_trace_ticks();

/// "shadow, light 2, 9-15 of 16 lanes" and the like, for a row of a packet `width` wide.
[[nodiscard]] std::string trace_tick_row_name(const TraceTickRow& row, unsigned width);

/// What the next trace call on this thread traces: set by the renderer right before each call
/// (trace_tick_next), read by its TraceTickScope. A thread-local rather than arguments, so that a
/// default build's trace calls keep their signatures and compile to the same code.
struct TraceTickWhat {
  TraceCall call = TraceCall::Primary;
  int light = -1;
};
inline thread_local TraceTickWhat t_trace_tick_what;

/// Names what the next trace call on this thread traces (`light`: Shadow only). The renderer
/// calls it under `if constexpr (kTraceTicks)`, so that a default build's kernels do not even
/// compute its arguments.
inline void trace_tick_next(TraceCall call, std::size_t light = 0) {
  if constexpr (kTraceTicks) {
    const std::size_t row = std::min<std::size_t>(light, kTraceTickLights - 1);
    t_trace_tick_what = {call, call == TraceCall::Shadow ? static_cast<int>(row) : -1};
  }
}

/// Times one trace call of `rays` rays in a packet of `width` lanes, from construction to
/// destruction, into the tally as what trace_tick_next last named. The renderer declares it
/// through RTC_TRACE_TICK_SCOPE, which is nothing unless kTraceTicks.
class TraceTickScope {
 public:
  TraceTickScope(bool external, unsigned rays, unsigned width) : external_(external), rays_(rays), width_(width) {
    if constexpr (kTraceTicks) {
      what_ = t_trace_tick_what;
      start_ = read_tsc();
    }
  }
  ~TraceTickScope() {
    if constexpr (kTraceTicks) {
      add_trace_ticks(external_, what_.call, what_.light, lane_fill(rays_, width_), read_tsc() - start_, rays_);
    }
  }
  TraceTickScope(const TraceTickScope&) = delete;
  TraceTickScope& operator=(const TraceTickScope&) = delete;

 private:
  bool external_;
  unsigned rays_, width_;
  TraceTickWhat what_;
  std::uint64_t start_ = 0;
};

}  // namespace rtc

/// One TraceTickScope for the rest of the enclosing block, in an RTC_TRACE_TICKS build; nothing
/// at all otherwise, its arguments not even evaluated, so that a default build's trace calls
/// compile to the instructions they had without it (when it came in, render_kernels.cpp's
/// objects disassembled to the same instructions as before, on every ISA; an empty timer object
/// and the kind passed as an argument had changed their register allocation).
#if RTC_TRACE_TICKS
#define RTC_TRACE_TICK_SCOPE(external, rays, width) const ::rtc::TraceTickScope rtc_trace_tick_scope_(external, rays, width)
#else
#define RTC_TRACE_TICK_SCOPE(external, rays, width) static_cast<void>(0)
#endif
