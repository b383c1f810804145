// kd-tree extremes: 10 million triangles, a million triangles in one spot (the depth limit),
// every triangle identical. The build finishes within the test's timeout and sampled rays
// equal brute force at every ISA.
#include <gtest/gtest.h>

#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>

#include "common/accel/kd_tree.h"
#include "common/accel/trace.h"
#include "tests/stress/stress_support.h"

namespace rtc::stress {
namespace {

double peak_rss_mib() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_maxrss) / 1024.0;  // Linux: KiB
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// A fractal-ish terrain over a (side x side) vertex grid: 2 (side - 1)^2 triangles sharing
// vertices, with overhanging random triangles above it so that rays see two kinds of geometry.
Soup terrain(int side, std::uint32_t seed) {
  Soup s;
  s.positions.reserve(static_cast<std::size_t>(side) * side);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> jitter(-0.002f, 0.002f);
  const float step = 2.0f / static_cast<float>(side - 1);
  for (int j = 0; j < side; ++j) {
    for (int i = 0; i < side; ++i) {
      const float x = -1.0f + step * static_cast<float>(i), z = -1.0f + step * static_cast<float>(j);
      const float y = 0.2f * std::sin(3.1f * x) * std::cos(2.3f * z) + 0.05f * std::sin(17.0f * x + 11.0f * z) + jitter(rng);
      s.positions.emplace_back(x, y, z);
    }
  }
  s.triangles.reserve(2 * static_cast<std::size_t>(side - 1) * (side - 1));
  for (int j = 0; j + 1 < side; ++j) {
    for (int i = 0; i + 1 < side; ++i) {
      const auto a = static_cast<unsigned>(j * side + i), b = a + 1, c = a + static_cast<unsigned>(side), d = c + 1;
      s.triangles.emplace_back(a, c, b);
      s.triangles.emplace_back(b, c, d);
    }
  }
  return s;
}

void check_rays(const KdTree& tree, const Soup& s, const std::vector<RayQuery>& rays, const std::string& what) {
  const auto t0 = std::chrono::steady_clock::now();
  const BruteForce oracle(s.positions, s.triangles);
  const Agreement a = expect_agrees_with_brute_force(tree, oracle, rays, what);
  std::printf("%s: %s (brute force and compare %.1f s)\n", what.c_str(), a.summary().c_str(), seconds_since(t0));
  EXPECT_EQ(a.mismatches, 0u) << what;
  std::vector<RayHit> hits(rays.size());
  trace_kernels().intersect(tree, rays.data(), hits.data(), rays.size(), true);
  EXPECT_EQ(check_hit_sanity(s.positions, s.triangles, rays, hits, what), 0u);
}

TEST(StressTree, TenMillionTriangles) {
  // 2237^2 vertices: 2 * 2236^2 = 9,999,392 terrain triangles, plus 608 random ones above it
  // (seed 211) to make it 10,000,000.
  const auto t0 = std::chrono::steady_clock::now();
  Soup s = terrain(2237, 211);
  std::mt19937 rng(211);
  std::uniform_real_distribution<float> pos(-1.0f, 1.0f), off(-0.05f, 0.05f);
  while (s.triangles.size() < 10000000) {
    const glm::vec3 c(pos(rng), 0.4f + 0.2f * pos(rng), pos(rng));
    s.add(c + glm::vec3(off(rng), off(rng), off(rng)), c + glm::vec3(off(rng), off(rng), off(rng)),
          c + glm::vec3(off(rng), off(rng), off(rng)));
  }
  ASSERT_EQ(s.triangles.size(), 10000000u);
  const double generate_s = seconds_since(t0);
  const KdTree tree = KdTree::build(s.positions, s.triangles);
  std::printf("10 M triangles: generated in %.1f s; %s; peak RSS %.0f MiB after the build\n", generate_s,
              tree.stats().to_string().c_str(), peak_rss_mib());
  EXPECT_EQ(tree.stats().degenerate, 0u);
  // Seeds 213 (rays at random terrain points: nearly all hit) and 217 (random); few rays, as the
  // brute force over 10 M triangles costs about 0.3 s of 2 cores per ray.
  std::vector<RayQuery> rays = rays_at_triangles(213, 32, s, bounds_of(s));
  const std::vector<RayQuery> random = random_rays(217, 16, bounds_of(s));
  rays.insert(rays.end(), random.begin(), random.end());
  check_rays(tree, s, rays, "10 M triangles");
  std::printf("10 M triangles: whole test %.1f s, peak RSS %.0f MiB\n", seconds_since(t0), peak_rss_mib());
}

TEST(StressTree, MillionTrianglesInOneSpotReachTheDepthLimit) {
  // Seed 223. A million triangles of size ~1e-4 packed in a cube of side 1e-2 at (0.3, 0.3,
  // 0.3), inside a room of 12 triangles of size 2: splitting keeps paying until the depth
  // limit (8 + 1.3 log2 N = 33 here) stops it. Then once more with max_depth = 60, the largest
  // the traversal stack (64 entries) is sized for, and perfect splits to the leaves (no bit-mask
  // stage, whose unclipped straddlers stop the SAH at depth 33 here, so it would not show that
  // the limit let the tree go deeper).
  std::mt19937 rng(223);
  std::uniform_real_distribution<float> pos(0.295f, 0.305f), off(-1e-4f, 1e-4f);
  Soup s;
  for (int i = 0; i < 1000000; ++i) {
    const glm::vec3 c(pos(rng), pos(rng), pos(rng));
    s.add(c + glm::vec3(off(rng), off(rng), off(rng)), c + glm::vec3(off(rng), off(rng), off(rng)),
          c + glm::vec3(off(rng), off(rng), off(rng)));
  }
  const glm::vec3 p[8] = {{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1},
                          {-1, -1, 1},  {1, -1, 1},  {1, 1, 1},  {-1, 1, 1}};
  const int faces[6][4] = {{0, 1, 2, 3}, {4, 5, 6, 7}, {0, 1, 5, 4}, {2, 3, 7, 6}, {0, 3, 7, 4}, {1, 2, 6, 5}};
  for (const auto& f : faces) {
    s.add(p[f[0]], p[f[1]], p[f[2]]);
    s.add(p[f[0]], p[f[2]], p[f[3]]);
  }
  // Rays from around the room into the cluster (seed 227) and random ones (seed 229).
  Aabb cluster;
  cluster.extend(glm::vec3(0.295f));
  cluster.extend(glm::vec3(0.305f));
  std::vector<RayQuery> rays;
  std::uniform_real_distribution<float> room(-0.9f, 0.9f), target(0.296f, 0.304f);
  std::mt19937 rng2(227);
  for (int i = 0; i < 120; ++i) {
    RayQuery r;
    r.org = glm::vec3(room(rng2), room(rng2), room(rng2));
    r.dir = glm::vec3(target(rng2), target(rng2), target(rng2)) - r.org;
    rays.push_back(r);
  }
  for (const RayQuery& r : random_rays(229, 40, cluster)) rays.push_back(r);

  for (const int depth_limit : {0, 60}) {
    KdBuildOptions o;
    o.max_depth = depth_limit;
    // The cost model the depths above were measured with (K_T = 3, K_I = 1.5, 2026-11-22: 33,
    // and 34 with the limit at 60). K_I = 1, the default since, stops at depth 30 (splitting
    // pays less) and would not reach the limit.
    o.traversal_cost = 3.0f;
    o.intersection_cost = 1.5f;
    if (depth_limit == 60) o.mask_below = 0;
    const auto t0 = std::chrono::steady_clock::now();
    const KdTree tree = KdTree::build(s.positions, s.triangles, o);
    const int automatic = static_cast<int>(8.0 + 1.3 * std::log2(static_cast<double>(s.triangles.size())));
    std::printf("one spot, max_depth option %d: built in %.1f s; %s\n", depth_limit, seconds_since(t0),
                tree.stats().to_string().c_str());
    if (depth_limit == 0) {
      EXPECT_EQ(tree.stats().max_depth, automatic) << "the depth limit was meant to be reached";
    } else {
      // Allowed deeper, the SAH goes past the automatic limit (measured: 34) and stops itself.
      EXPECT_GT(tree.stats().max_depth, automatic);
      EXPECT_LE(tree.stats().max_depth, depth_limit);
    }
    check_rays(tree, s, rays, "one spot, max_depth " + std::to_string(depth_limit));
  }
}

TEST(StressTree, AllTrianglesIdentical) {
  // 200 K copies of one triangle: no plane separates them, so one leaf holds all; every hit is
  // the highest id. Rays (seed 233) through it and around it.
  Soup s;
  s.positions = {{-0.5f, -0.4f, 0.1f}, {0.6f, -0.3f, -0.2f}, {0.0f, 0.7f, 0.3f}};
  s.triangles.assign(200000, glm::uvec3(0, 1, 2));
  const KdTree tree = KdTree::build(s.positions, s.triangles);
  std::printf("identical: %s\n", tree.stats().to_string().c_str());
  std::vector<RayQuery> rays = rays_at_triangles(233, 150, s, bounds_of(s));
  for (const RayQuery& r : random_rays(239, 100, bounds_of(s))) rays.push_back(r);
  check_rays(tree, s, rays, "identical triangles");
  std::vector<RayHit> hits(rays.size());
  trace_kernels().intersect(tree, rays.data(), hits.data(), rays.size(), true);
  std::size_t hit = 0;
  for (const RayHit& h : hits) {
    if (h.prim == kNoHit) continue;
    ++hit;
    EXPECT_EQ(h.prim, 199999u);
  }
  EXPECT_GT(hit, 125u);
}

}  // namespace
}  // namespace rtc::stress
