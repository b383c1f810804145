#include "common/accel/walk_stats.h"

#include <array>
#include <atomic>
#include <cstdio>

namespace rtc {
namespace {

struct Totals {
  std::atomic<std::uint64_t> walks{0}, lanes{0}, inner{0}, leaves{0}, empty_leaves{0}, pushes{0}, tests{0},
      test_lanes{0};
};

// [packet][occlusion]
std::array<std::array<Totals, 2>, 2> g_totals;

double per(std::uint64_t n, std::uint64_t d) { return d > 0 ? static_cast<double>(n) / static_cast<double>(d) : 0.0; }

}  // namespace

WalkStats& WalkStats::operator+=(const WalkStats& o) {
  walks += o.walks;
  lanes += o.lanes;
  inner += o.inner;
  leaves += o.leaves;
  empty_leaves += o.empty_leaves;
  pushes += o.pushes;
  tests += o.tests;
  test_lanes += o.test_lanes;
  return *this;
}

std::string WalkStats::to_string() const {
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "walks %llu, lanes %.2f/walk, inner %.2f, leaves %.2f (+%.2f empty), pushes %.2f, "
                "tests %.2f x %.2f lanes",
                static_cast<unsigned long long>(walks), per(lanes, walks), per(inner, walks), per(leaves, walks),
                per(empty_leaves, walks), per(pushes, walks), per(tests, walks), per(test_lanes, tests));
  return buf;
}

WalkStats walk_stats(bool packet, bool occlusion) {
  const Totals& t = g_totals[packet][occlusion];
  WalkStats s;
  s.walks = t.walks.load();
  s.lanes = t.lanes.load();
  s.inner = t.inner.load();
  s.leaves = t.leaves.load();
  s.empty_leaves = t.empty_leaves.load();
  s.pushes = t.pushes.load();
  s.tests = t.tests.load();
  s.test_lanes = t.test_lanes.load();
  return s;
}

void reset_walk_stats() {
  for (auto& by_kind : g_totals) {
    for (Totals& t : by_kind) {
      for (std::atomic<std::uint64_t>* a :
           {&t.walks, &t.lanes, &t.inner, &t.leaves, &t.empty_leaves, &t.pushes, &t.tests, &t.test_lanes}) {
        a->store(0);
      }
    }
  }
}

void add_walk_stats(bool packet, bool occlusion, const WalkStats& s) {
  Totals& t = g_totals[packet][occlusion];
  constexpr auto relaxed = std::memory_order_relaxed;
  t.walks.fetch_add(s.walks, relaxed);
  t.lanes.fetch_add(s.lanes, relaxed);
  t.inner.fetch_add(s.inner, relaxed);
  t.leaves.fetch_add(s.leaves, relaxed);
  t.empty_leaves.fetch_add(s.empty_leaves, relaxed);
  t.pushes.fetch_add(s.pushes, relaxed);
  t.tests.fetch_add(s.tests, relaxed);
  t.test_lanes.fetch_add(s.test_lanes, relaxed);
}

}  // namespace rtc
