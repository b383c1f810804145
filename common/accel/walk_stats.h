// What kd-tree walks did: inner-node steps, leaves, triangle tests and the lanes live in them,
// per walk. Compiled in only with the CMake option RTC_WALK_STATS (the `stats` preset): the
// counting costs trace time, so a default build counts nothing and its walks carry no trace of
// it. rtc-bench prints the counts per mode (tests/bench/run_walk_stats.sh tabulates the shared
// scenes). Not compiled per ISA.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>

#ifndef RTC_WALK_STATS
#define RTC_WALK_STATS 0
#endif

namespace rtc {

/// Whether this build counts (RTC_WALK_STATS).
inline constexpr bool kWalkStats = RTC_WALK_STATS != 0;

/// Totals over walks. A walk is one traverse_coherent call: a packet (or a same-octant group of
/// its lanes) or one ray. Lanes are counted where the walk starts (those whose segment meets the
/// tree's box) and at each triangle test (test_lanes: the lanes live in it).
struct WalkStats {
  std::uint64_t walks = 0;
  std::uint64_t lanes = 0;
  std::uint64_t inner = 0;         // inner-node steps
  std::uint64_t leaves = 0;        // leaves with triangles entered
  std::uint64_t empty_leaves = 0;  // empty leaves entered (packets pass marked ones by)
  std::uint64_t pushes = 0;        // subtrees stacked
  std::uint64_t tests = 0;         // triangle records tested (a leaf tested side by side counts each)
  std::uint64_t test_lanes = 0;
  std::uint64_t box_tests = 0;     // leaves whose LeafBox was tested
  std::uint64_t box_skips = 0;     // ... of which no lane's segment met the box (no triangle tested)
  std::uint64_t box_lanes = 0;     // lanes live at the box tests
  std::uint64_t box_kept = 0;      // ... of which the box kept (their segment meets it)

  WalkStats& operator+=(const WalkStats& o);
  /// Per walk: "walks W, lanes L/walk, inner I, leaves F (+E empty), pushes P, tests T x N lanes,
  /// leaf boxes B (S skipped), lanes K of M kept".
  [[nodiscard]] std::string to_string() const;
};

/// Every counter of WalkStats with its name (the JSON keys rtc-bench writes): the one list that
/// summing, the totals and the JSON go through.
inline constexpr std::array<std::pair<const char*, std::uint64_t WalkStats::*>, 12> kWalkStatsFields = {{
    {"walks", &WalkStats::walks},
    {"lanes", &WalkStats::lanes},
    {"inner", &WalkStats::inner},
    {"leaves", &WalkStats::leaves},
    {"empty_leaves", &WalkStats::empty_leaves},
    {"pushes", &WalkStats::pushes},
    {"tests", &WalkStats::tests},
    {"test_lanes", &WalkStats::test_lanes},
    {"box_tests", &WalkStats::box_tests},
    {"box_skips", &WalkStats::box_skips},
    {"box_lanes", &WalkStats::box_lanes},
    {"box_kept", &WalkStats::box_kept},
}};

/// The totals kept: walks of one ray (`packet` false) or of packets, closest hit or occlusion.
[[nodiscard]] WalkStats walk_stats(bool packet, bool occlusion);
/// Sets every total to zero (call it with no walk running).
void reset_walk_stats();
/// Adds one walk's counts to its totals (thread-safe). Called by the walks of a stats build only.
void add_walk_stats(bool packet, bool occlusion, const WalkStats& s);

/// The distinct 64-byte cache lines that walks read (or asked for ahead) from one tree's nodes
/// and leaf slots (LeafBox and triangle records), over the walks since track_walk_footprint:
/// the tree's working set for those rays, which decides how much of it an L2 holds. Stats
/// builds only; walks over other trees are not counted.
struct WalkFootprint {
  std::uint64_t node_lines = 0;
  std::uint64_t record_lines = 0;
  [[nodiscard]] double node_mb() const { return static_cast<double>(node_lines) * 64.0 / 1e6; }
  [[nodiscard]] double record_mb() const { return static_cast<double>(record_lines) * 64.0 / 1e6; }
};
/// Starts counting the lines read from [nodes, nodes + node_bytes) and [records, records +
/// record_bytes) (one tree's arrays), with none counted yet. Call it with no walk running.
void track_walk_footprint(const void* nodes, std::size_t node_bytes, const void* records, std::size_t record_bytes);
/// The lines counted since track_walk_footprint (zeros when not tracking).
[[nodiscard]] WalkFootprint walk_footprint();
/// Stops counting and frees the line marks. Call it with no walk running.
void stop_walk_footprint();
/// Marks the lines of [p, p + bytes) when the whole range lies in one tracked array (thread-safe;
/// a range outside them, or reaching past one's end, marks nothing). Called by the walks of a
/// stats build only.
void mark_walk_lines(const void* p, std::size_t bytes);

/// One walk's counts, added to the totals when it goes out of scope. Where kWalkStats is false
/// every member function is empty and the object holds nothing, so the walk compiles as if it
/// were not there.
template <bool kEnabled>
struct WalkCounter {
  WalkCounter(bool, bool) {}
  void start(std::uint32_t) {}
  void inner() {}
  void push() {}
  void leaf(std::uint32_t) {}
  void tests(std::uint32_t, std::uint32_t) {}
  void box(std::uint32_t, std::uint32_t) {}
  void read(const void*, std::size_t) {}
};

template <>
struct WalkCounter<true> {
  WalkCounter(bool packet, bool occlusion) : packet_(packet), occlusion_(occlusion) {}
  WalkCounter(const WalkCounter&) = delete;
  WalkCounter& operator=(const WalkCounter&) = delete;
  ~WalkCounter() {
    if (s_.walks != 0) add_walk_stats(packet_, occlusion_, s_);
  }
  void start(std::uint32_t lanes) {
    s_.walks = 1;
    s_.lanes = lanes;
  }
  void inner() { ++s_.inner; }
  void push() { ++s_.pushes; }
  void leaf(std::uint32_t count) { ++(count == 0 ? s_.empty_leaves : s_.leaves); }
  // `count` triangles tested, each with `lanes` live lanes.
  void tests(std::uint32_t count, std::uint32_t lanes) {
    s_.tests += count;
    s_.test_lanes += static_cast<std::uint64_t>(count) * lanes;
  }
  // A LeafBox tested with `lanes` live lanes, `kept` of them meeting it.
  void box(std::uint32_t lanes, std::uint32_t kept) {
    ++s_.box_tests;
    s_.box_skips += kept == 0;
    s_.box_lanes += lanes;
    s_.box_kept += kept;
  }
  // `bytes` read (or asked for ahead) at p: counted in the footprint where it is tracked.
  void read(const void* p, std::size_t bytes) { mark_walk_lines(p, bytes); }

 private:
  WalkStats s_;
  bool packet_, occlusion_;
};

}  // namespace rtc
