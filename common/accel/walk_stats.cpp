#include "common/accel/walk_stats.h"

#include <array>
#include <atomic>
#include <cstdio>

namespace rtc {
namespace {

// One atomic per counter, in kWalkStatsFields order.
using Totals = std::array<std::atomic<std::uint64_t>, kWalkStatsFields.size()>;

// [packet][occlusion]
std::array<std::array<Totals, 2>, 2> g_totals;

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

}  // namespace rtc
