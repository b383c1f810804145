#include "common/accel/walk_stats.h"

#include <array>
#include <atomic>
#include <cstdio>
#include <memory>

namespace rtc {
namespace {

// One atomic per counter, in kWalkStatsFields order.
using Totals = std::array<std::atomic<std::uint64_t>, kWalkStatsFields.size()>;

// [packet][occlusion]
std::array<std::array<Totals, 2>, 2> g_totals;

// The footprint's tracked arrays and a mark per line of each (track_walk_footprint).
struct Tracked {
  std::uintptr_t begin = 0, end = 0;  // bytes
  std::unique_ptr<std::atomic<std::uint8_t>[]> marks;
  std::size_t lines = 0;
  void reset(const void* p, std::size_t bytes) {
    begin = reinterpret_cast<std::uintptr_t>(p);
    end = begin + bytes;
    lines = bytes == 0 ? 0 : (end - 1) / 64 - begin / 64 + 1;
    marks = lines == 0 ? nullptr : std::make_unique<std::atomic<std::uint8_t>[]>(lines);  // zeros
  }
  void mark(std::uintptr_t from, std::uintptr_t to) {  // [from, to) within [begin, end)
    for (std::uintptr_t line = from / 64; line <= (to - 1) / 64; ++line) {
      std::atomic<std::uint8_t>& m = marks[line - begin / 64];
      // Read first: a line marked already is not written again (both cores would otherwise
      // keep taking the line of marks from each other).
      if (m.load(std::memory_order_relaxed) == 0) m.store(1, std::memory_order_relaxed);
    }
  }
  [[nodiscard]] std::uint64_t count() const {
    std::uint64_t n = 0;
    for (std::size_t i = 0; i < lines; ++i) n += marks[i].load(std::memory_order_relaxed);
    return n;
  }
};
Tracked g_nodes, g_records;

double per(std::uint64_t n, std::uint64_t d) { return d > 0 ? static_cast<double>(n) / static_cast<double>(d) : 0.0; }

}  // namespace

WalkStats& WalkStats::operator+=(const WalkStats& o) {
  for (const auto& [name, field] : kWalkStatsFields) this->*field += o.*field;
  return *this;
}

std::string WalkStats::to_string() const {
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "walks %llu, lanes %.2f/walk, inner %.2f, leaves %.2f (+%.2f empty), pushes %.2f, "
                "tests %.2f x %.2f lanes, leaf boxes %.2f (%.2f skipped), lanes %.2f of %.2f kept",
                static_cast<unsigned long long>(walks), per(lanes, walks), per(inner, walks), per(leaves, walks),
                per(empty_leaves, walks), per(pushes, walks), per(tests, walks), per(test_lanes, tests),
                per(box_tests, walks), per(box_skips, walks), per(box_kept, box_tests), per(box_lanes, box_tests));
  return buf;
}

WalkStats walk_stats(bool packet, bool occlusion) {
  const Totals& t = g_totals[packet][occlusion];
  WalkStats s;
  for (std::size_t i = 0; i < t.size(); ++i) s.*kWalkStatsFields[i].second = t[i].load();
  return s;
}

void reset_walk_stats() {
  for (auto& by_kind : g_totals) {
    for (Totals& t : by_kind) {
      for (std::atomic<std::uint64_t>& a : t) a.store(0);
    }
  }
}

void add_walk_stats(bool packet, bool occlusion, const WalkStats& s) {
  Totals& t = g_totals[packet][occlusion];
  for (std::size_t i = 0; i < t.size(); ++i) t[i].fetch_add(s.*kWalkStatsFields[i].second, std::memory_order_relaxed);
}

void track_walk_footprint(const void* nodes, std::size_t node_bytes, const void* records, std::size_t record_bytes) {
  g_nodes.reset(nodes, node_bytes);
  g_records.reset(records, record_bytes);
}

WalkFootprint walk_footprint() { return WalkFootprint{g_nodes.count(), g_records.count()}; }

void stop_walk_footprint() {
  g_nodes.reset(nullptr, 0);
  g_records.reset(nullptr, 0);
}

void mark_walk_lines(const void* p, std::size_t bytes) {
  if (bytes == 0) return;
  const auto from = reinterpret_cast<std::uintptr_t>(p), to = from + bytes;
  for (Tracked* t : {&g_nodes, &g_records}) {
    if (t->lines != 0 && from >= t->begin && to <= t->end) t->mark(from, to);
  }
}

}  // namespace rtc
