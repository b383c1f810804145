// Walk counts (RTC_WALK_STATS): summed and printed right, nothing counted in a default build,
// and in a stats build (the stats preset) counts that follow from the tree and the rays.
#include <gtest/gtest.h>

#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/accel/kd_tree.h"
#include "common/accel/trace.h"
#include "common/accel/walk_stats.h"

namespace rtc {
namespace {

TEST(WalkStats, SumsAndPrintsPerWalk) {
  WalkStats a;
  a.walks = 2;
  a.lanes = 16;
  a.inner = 10;
  a.leaves = 4;
  a.empty_leaves = 1;
  a.pushes = 3;
  a.tests = 8;
  a.test_lanes = 20;
  a.box_tests = 3;
  a.box_skips = 1;
  a.box_lanes = 12;
  a.box_kept = 6;
  WalkStats b = a;
  b += a;
  EXPECT_EQ(b.walks, 4u);
  EXPECT_EQ(b.test_lanes, 40u);
  EXPECT_EQ(b.to_string(),
            "walks 4, lanes 8.00/walk, inner 5.00, leaves 2.00 (+0.50 empty), pushes 1.50, tests 4.00 x 2.50 lanes, "
            "leaf boxes 1.50 (0.50 skipped), lanes 2.00 of 4.00 kept");
  EXPECT_EQ(WalkStats{}.to_string(),
            "walks 0, lanes 0.00/walk, inner 0.00, leaves 0.00 (+0.00 empty), pushes 0.00, tests 0.00 x 0.00 lanes, "
            "leaf boxes 0.00 (0.00 skipped), lanes 0.00 of 0.00 kept");
}

// Rays down the z axis through a grid of n x n unit squares (two triangles each) at z = 0,
// one ray per square (inside one triangle, off the diagonal), all starting above the grid.
struct Grid {
  std::vector<glm::vec3> positions;
  std::vector<glm::uvec3> triangles;
  std::vector<RayQuery> rays;
};

Grid grid(int n) {
  Grid g;
  for (int y = 0; y <= n; ++y) {
    for (int x = 0; x <= n; ++x) g.positions.emplace_back(static_cast<float>(x), static_cast<float>(y), 0.0f);
  }
  const auto v = [n](int x, int y) { return static_cast<std::uint32_t>(y * (n + 1) + x); };
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      g.triangles.emplace_back(v(x, y), v(x + 1, y), v(x + 1, y + 1));
      g.triangles.emplace_back(v(x, y), v(x + 1, y + 1), v(x, y + 1));
      RayQuery r;
      r.org = glm::vec3(static_cast<float>(x) + 0.3f, static_cast<float>(y) + 0.6f, 1.0f);
      r.dir = glm::vec3(0.0f, 0.0f, -1.0f);
      r.t_min = 0.0f;
      r.t_max = 2.0f;  // the grid at t = 1
      g.rays.push_back(r);
    }
  }
  return g;
}

TEST(WalkStats, CountsWhatTheWalksDid) {
  const Grid g = grid(16);
  const KdTree tree = KdTree::build(g.positions, g.triangles, KdBuildOptions{});
  std::vector<RayHit> hits(g.rays.size());
  std::vector<std::uint8_t> occluded(g.rays.size());
  const TraceKernels& k = trace_kernels();

  reset_walk_stats();
  k.intersect(tree, g.rays.data(), hits.data(), g.rays.size(), false);
  const WalkStats single = walk_stats(false, false);
  for (const RayHit& h : hits) ASSERT_NE(h.prim, kNoHit);
  reset_walk_stats();
  k.intersect(tree, g.rays.data(), hits.data(), g.rays.size(), true);
  const WalkStats packets = walk_stats(true, false);
  const WalkStats lone = walk_stats(false, false);
  reset_walk_stats();
  k.occluded(tree, g.rays.data(), occluded.data(), g.rays.size(), false);
  const WalkStats shadow = walk_stats(false, true);
  reset_walk_stats();

  if (!kWalkStats) {
    // A default build counts nothing: the walks carry no counting code.
    for (const WalkStats& s : {single, packets, lone, shadow}) {
      EXPECT_EQ(s.walks, 0u);
      EXPECT_EQ(s.inner, 0u);
      EXPECT_EQ(s.tests, 0u);
    }
    return;
  }
  const std::uint64_t rays = g.rays.size();
  // One walk per ray, one lane each; every ray reaches the grid, so a leaf with triangles.
  EXPECT_EQ(single.walks, rays);
  EXPECT_EQ(single.lanes, rays);
  EXPECT_EQ(single.test_lanes, single.tests);
  EXPECT_GE(single.leaves, rays);
  EXPECT_GE(single.tests, rays);
  EXPECT_LE(single.pushes, single.inner);
  // The grid has 512 triangles: the tree has inner nodes, and every ray takes some.
  ASSERT_GT(tree.nodes().size(), 1u);
  EXPECT_GE(single.inner, rays);
  // Packets: the rays' lanes in walks of up to the packet width (one octant: no lone lanes),
  // fewer walks than rays; a packet visits the union of its rays' nodes, so no more in all.
  const std::uint64_t width = static_cast<std::uint64_t>(k.packet_width);
  EXPECT_EQ(lone.walks, 0u);
  EXPECT_EQ(packets.lanes, rays);
  EXPECT_GE(packets.walks * width, rays);
  EXPECT_LT(packets.walks, rays);
  EXPECT_LE(packets.test_lanes, packets.tests * width);
  EXPECT_LE(packets.inner, single.inner);
  EXPECT_LE(packets.leaves, single.leaves);
  // Occlusion stops at the first hit: never more tests than the closest-hit walks made.
  EXPECT_EQ(shadow.walks, rays);
  EXPECT_LE(shadow.tests, single.tests);
  EXPECT_GE(shadow.tests, rays);
}

// A tree of one leaf: no inner node, and each ray walks straight to it.
TEST(WalkStats, OneLeafTreeHasNoInnerSteps) {
  if (!kWalkStats) GTEST_SKIP() << "built without RTC_WALK_STATS (the stats preset counts)";
  const std::vector<glm::vec3> positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const std::vector<glm::uvec3> triangles = {{0, 1, 2}};
  const KdTree tree = KdTree::build(positions, triangles, KdBuildOptions{});
  ASSERT_EQ(tree.nodes().size(), 1u);
  std::vector<RayQuery> rays(10);
  for (int i = 0; i < 10; ++i) {
    rays[i].org = glm::vec3(0.05f * static_cast<float>(i) + 0.01f, 0.1f, 1.0f);
    rays[i].dir = glm::vec3(0.0f, 0.0f, -1.0f);
    rays[i].t_min = 0.0f;
    rays[i].t_max = 2.0f;
  }
  std::vector<RayHit> hits(rays.size());
  reset_walk_stats();
  trace_kernels().intersect(tree, rays.data(), hits.data(), rays.size(), false);
  const WalkStats s = walk_stats(false, false);
  reset_walk_stats();
  EXPECT_EQ(s.walks, 10u);
  EXPECT_EQ(s.inner, 0u);
  EXPECT_EQ(s.pushes, 0u);
  EXPECT_EQ(s.leaves, 10u);
  EXPECT_EQ(s.empty_leaves, 0u);
  EXPECT_EQ(s.tests, 10u);
}

// The lines [p, p + bytes) spans.
std::uint64_t lines_spanned(const void* p, std::size_t bytes) {
  const auto a = reinterpret_cast<std::uintptr_t>(p);
  return bytes == 0 ? 0 : (a + bytes - 1) / 64 - a / 64 + 1;
}

// The line arithmetic on two aligned arrays (any build: the marks are plain functions).
TEST(WalkStats, FootprintMarksTheLinesARangeSpans) {
  alignas(64) static std::uint8_t nodes[64 * 8];
  alignas(64) static std::uint8_t records[64 * 16];
  track_walk_footprint(nodes, sizeof nodes, records, sizeof records);
  mark_walk_lines(nodes + 60, 8);          // lines 0 and 1
  mark_walk_lines(nodes + 64, 64);         // line 1 again
  mark_walk_lines(nodes + 128, 0);         // nothing
  mark_walk_lines(nodes + 500, 40);        // past the end: nothing
  mark_walk_lines(records + 64 * 15, 64);  // the last line
  mark_walk_lines(records + 10, 1);        // the first
  mark_walk_lines(records + 200, 200);     // lines 3-6
  static std::uint8_t elsewhere[64];
  mark_walk_lines(elsewhere, sizeof elsewhere);  // in neither array
  const WalkFootprint f = walk_footprint();
  EXPECT_EQ(f.node_lines, 2u);
  EXPECT_EQ(f.record_lines, 6u);
  EXPECT_DOUBLE_EQ(f.record_mb(), 6 * 64 / 1e6);
  track_walk_footprint(nodes, sizeof nodes, records, sizeof records);  // starts again from none
  EXPECT_EQ(walk_footprint().node_lines + walk_footprint().record_lines, 0u);
  stop_walk_footprint();
  mark_walk_lines(nodes, 64);
  EXPECT_EQ(walk_footprint().node_lines, 0u);
}

// The footprint: the distinct lines of a tracked tree's nodes and leaf slots that walks read.
TEST(WalkStats, FootprintCountsTheLinesRead) {
  const Grid g = grid(16);
  const KdTree tree = KdTree::build(g.positions, g.triangles, KdBuildOptions{});
  const auto track = [](const KdTree& t) {
    track_walk_footprint(t.nodes().data(), t.nodes().size_bytes(), t.leaf_records().data(),
                         t.leaf_records().size_bytes());
  };
  std::vector<RayHit> hits(g.rays.size());
  const TraceKernels& k = trace_kernels();
  track(tree);
  k.intersect(tree, g.rays.data(), hits.data(), g.rays.size(), true);
  const WalkFootprint packets = walk_footprint();
  track(tree);
  k.intersect(tree, g.rays.data(), hits.data(), g.rays.size(), false);
  const WalkFootprint single = walk_footprint();
  stop_walk_footprint();
  const WalkFootprint stopped = walk_footprint();
  EXPECT_EQ(stopped.node_lines, 0u);
  EXPECT_EQ(stopped.record_lines, 0u);
  if (!kWalkStats) {
    // A default build's walks mark nothing.
    EXPECT_EQ(packets.node_lines + packets.record_lines + single.node_lines + single.record_lines, 0u);
    return;
  }
  const std::uint64_t node_lines = lines_spanned(tree.nodes().data(), tree.nodes().size_bytes());
  const std::uint64_t record_lines = lines_spanned(tree.leaf_records().data(), tree.leaf_records().size_bytes());
  ASSERT_GT(node_lines, 4u);  // a tree of several lines of nodes
  for (const WalkFootprint& f : {packets, single}) {
    // Within the arrays, and at least the lines of the 256 triangles hit (one per square).
    EXPECT_LE(f.node_lines, node_lines);
    // The 256 rays reach leaves all over the tree: more than the root's line of nodes.
    EXPECT_GT(f.node_lines, node_lines / 2) << "of " << node_lines;
    EXPECT_LE(f.record_lines, record_lines);
    EXPECT_GE(f.record_lines * 64, 256u * sizeof(TriRecord));
  }
  // Every ray meets the grid, so together they read every leaf with a triangle hit; the two
  // kernels visit the same leaves.
  EXPECT_EQ(single.record_lines, packets.record_lines);

  // Rays that miss the tree's box read nothing; walks over a tree not tracked count nowhere.
  std::vector<RayQuery> away = g.rays;
  for (RayQuery& r : away) r.dir = glm::vec3(0.0f, 0.0f, 1.0f);
  track(tree);
  k.intersect(tree, away.data(), hits.data(), away.size(), false);
  const KdTree other = KdTree::build(g.positions, g.triangles, KdBuildOptions{});
  k.intersect(other, g.rays.data(), hits.data(), g.rays.size(), false);
  const WalkFootprint none = walk_footprint();
  EXPECT_EQ(none.node_lines, 0u);
  EXPECT_EQ(none.record_lines, 0u);

  // One leaf of one triangle: the root's line and the record's.
  const std::vector<glm::vec3> positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const std::vector<glm::uvec3> triangles = {{0, 1, 2}};
  const KdTree leaf = KdTree::build(positions, triangles, KdBuildOptions{});
  ASSERT_EQ(leaf.nodes().size(), 1u);
  RayQuery r;
  r.org = glm::vec3(0.2f, 0.2f, 1.0f);
  r.dir = glm::vec3(0.0f, 0.0f, -1.0f);
  r.t_max = 2.0f;
  track(leaf);
  k.intersect(leaf, &r, hits.data(), 1, false);
  const WalkFootprint one = walk_footprint();
  stop_walk_footprint();
  EXPECT_EQ(one.node_lines, 1u);
  EXPECT_EQ(one.record_lines, lines_spanned(leaf.leaf_records().data(), sizeof(TriRecord)));
}

}  // namespace
}  // namespace rtc
