// The trace-call tally (trace_ticks.h): atomic counters by side, kind and lane fill, shared by
// the threads that render.
#include "common/render/trace_ticks.h"

#include <algorithm>
#include <array>
#include <atomic>

namespace rtc {
namespace {

// Rows by kind: primary, mirror, then one per light.
constexpr int kKinds = 2 + kTraceTickLights;

struct Cell {
  std::atomic<std::uint64_t> ticks{0}, calls{0}, rays{0};
};

// [external][kind][fill]
std::array<std::array<std::array<Cell, kLaneFills>, kKinds>, 2> g_cells;

int kind_of(TraceCall call, int light) {
  switch (call) {
    case TraceCall::Primary:
      return 0;
    case TraceCall::Mirror:
      return 1;
    case TraceCall::Shadow:
      break;
  }
  return 2 + std::clamp(light, 0, kTraceTickLights - 1);
}

}  // namespace

void add_trace_ticks(bool external, TraceCall call, int light, LaneFill fill, std::uint64_t ticks, unsigned rays) {
  Cell& c = g_cells[external ? 1 : 0][static_cast<std::size_t>(kind_of(call, light))][static_cast<std::size_t>(fill)];
  c.ticks.fetch_add(ticks, std::memory_order_relaxed);
  c.calls.fetch_add(1, std::memory_order_relaxed);
  c.rays.fetch_add(rays, std::memory_order_relaxed);
}

std::vector<TraceTickRow> trace_ticks() {
  std::vector<TraceTickRow> rows;
  for (int side = 0; side < 2; ++side) {
    for (int kind = 0; kind < kKinds; ++kind) {
      for (int fill = 0; fill < kLaneFills; ++fill) {
        const Cell& c = g_cells[static_cast<std::size_t>(side)][static_cast<std::size_t>(kind)][static_cast<std::size_t>(fill)];
        TraceTickRow r;
        r.calls = c.calls.load(std::memory_order_relaxed);
        if (r.calls == 0) continue;
        r.external = side == 1;
        r.call = kind == 0 ? TraceCall::Primary : kind == 1 ? TraceCall::Mirror : TraceCall::Shadow;
        r.light = kind >= 2 ? kind - 2 : -1;
        r.fill = static_cast<LaneFill>(fill);
        r.ticks = c.ticks.load(std::memory_order_relaxed);
        r.rays = c.rays.load(std::memory_order_relaxed);
        rows.push_back(r);
      }
    }
  }
  return rows;
}

void reset_trace_ticks() {
  for (auto& side : g_cells) {
    for (auto& kind : side) {
      for (Cell& c : kind) {
        c.ticks.store(0, std::memory_order_relaxed);
        c.calls.store(0, std::memory_order_relaxed);
        c.rays.store(0, std::memory_order_relaxed);
      }
    }
  }
}

std::string trace_tick_row_name(const TraceTickRow& row, unsigned width) {
  std::string name = row.call == TraceCall::Primary ? "primary" : row.call == TraceCall::Mirror ? "mirror" : "shadow";
  if (row.call == TraceCall::Shadow) {
    name += ", light " + std::to_string(row.light);
    if (row.light == kTraceTickLights - 1) name += "+";
  }
  // The fill's range of lanes, "lo" or "lo-hi".
  const unsigned half = width / 2;
  unsigned lo = width, hi = width;
  switch (row.fill) {
    case LaneFill::Full:
      break;
    case LaneFill::MoreThanHalf:
      lo = half + 1, hi = width - 1;
      break;
    case LaneFill::AtMostHalf:
      lo = 1, hi = half;
      break;
  }
  name += ", " + std::to_string(lo);
  if (hi > lo) name += "-" + std::to_string(hi);
  return name + " of " + std::to_string(width) + " lanes";
}

}  // namespace rtc
