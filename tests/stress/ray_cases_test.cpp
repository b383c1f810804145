// Awkward rays through the kd-tree: axis-parallel and zero direction components (infinite
// inverse directions), origins exactly on split planes and on triangle edges, rays grazing a
// triangle's plane, packets whose lanes point into different octants. Every answer must be
// the brute-force answer, bit for bit, at every ISA, in packets and alone.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "common/accel/kd_tree.h"
#include "common/accel/trace.h"
#include "common/scene/tessellate.h"
#include "tests/stress/stress_support.h"

namespace rtc::stress {
namespace {

// An axis-aligned box made of grid quads (planar triangles lying on the planes the tree likes
// to split on), a cube-sphere (shared edges, every orientation), and a random soup.
Soup test_scene() {
  Soup s;
  const int n = 6;
  for (int axis = 0; axis < 3; ++axis) {
    for (const float side : {-1.0f, 1.0f}) {
      for (int i = 0; i < n; ++i) {
        for (int j = 0; j < n; ++j) {
          auto p = [&](int a, int b) {
            glm::vec3 v;
            v[axis] = side * 2.0f;
            v[(axis + 1) % 3] = -2.0f + 4.0f * static_cast<float>(a) / n;
            v[(axis + 2) % 3] = -2.0f + 4.0f * static_cast<float>(b) / n;
            return v;
          };
          s.add(p(i, j), p(i + 1, j), p(i + 1, j + 1));
          s.add(p(i, j), p(i + 1, j + 1), p(i, j + 1));
        }
      }
    }
  }
  const SphereTemplate sphere = make_cube_sphere(8);
  Soup ball;
  for (const glm::dvec3& q : sphere.points) ball.positions.push_back(glm::vec3(q * 0.7 + glm::dvec3(0.3, -0.2, 0.1)));
  ball.triangles = sphere.triangles;
  s.append(ball);
  std::mt19937 rng(41);
  std::uniform_real_distribution<float> pos(-1.8f, 1.8f), off(-0.2f, 0.2f);
  for (int i = 0; i < 1500; ++i) {
    const glm::vec3 c(pos(rng), pos(rng), pos(rng));
    s.add(c + glm::vec3(off(rng), off(rng), off(rng)), c + glm::vec3(off(rng), off(rng), off(rng)),
          c + glm::vec3(off(rng), off(rng), off(rng)));
  }
  return s;
}

// A LeafBox wherever a leaf's triangles fill less than its cell (KdBuildOptions::leaf_box_saving):
// the boxes' faces are planes just outside the triangles' extremes (the build widens them a
// little), which every case below must also pass.
KdBuildOptions boxes_everywhere() {
  KdBuildOptions o;
  o.leaf_box_saving = 1e-6f;
  return o;
}

struct Fixture {
  Soup soup = test_scene();
  KdTree tree = KdTree::build(soup.positions, soup.triangles);
  KdTree boxed = KdTree::build(soup.positions, soup.triangles, boxes_everywhere());
  BruteForce oracle{soup.positions, soup.triangles};
  Aabb box = bounds_of(soup);
};

const Fixture& fixture() {
  static const Fixture f;
  return f;
}

void run(const std::vector<RayQuery>& rays, const std::string& what, EdgeRounding edges = EdgeRounding::Exact) {
  const Fixture& f = fixture();
  ASSERT_GT(f.boxed.stats().leaf_boxes, 100u) << "too few leaf boxes to mean much";
  for (const KdTree* tree : {&f.tree, &f.boxed}) {
    const std::string name = what + (tree == &f.boxed ? " (leaf boxes everywhere)" : "");
    const Agreement a = expect_agrees_with_brute_force(*tree, f.oracle, rays, name, edges);
    std::vector<RayHit> hits(rays.size());
    trace_kernels().intersect(*tree, rays.data(), hits.data(), rays.size(), true);
    EXPECT_EQ(check_hit_sanity(f.soup.positions, f.soup.triangles, rays, hits, name), 0u);
    std::printf("%s: %s\n", name.c_str(), a.summary().c_str());
    EXPECT_EQ(a.mismatches, 0u) << name << ": " << a.summary();
    EXPECT_GT(a.hits, rays.size() / 10) << name << ": too few hits to mean much";
    // Shadow rays walked from the light's end, or denser child first, answer as those walked
    // from the origin, also where leaf boxes drop lanes (packets and alone).
    for (const bool packets : {true, false}) {
      std::vector<std::uint8_t> near(rays.size());
      trace_kernels().occluded_in_order(*tree, rays.data(), near.data(), rays.size(), packets, ShadowOrder::Near,
                                        nullptr);
      for (const ShadowOrder order : {ShadowOrder::Far, ShadowOrder::Dense}) {
        std::vector<std::uint8_t> other(rays.size());
        trace_kernels().occluded_in_order(*tree, rays.data(), other.data(), rays.size(), packets, order, nullptr);
        std::size_t differ = 0;
        for (std::size_t i = 0; i < rays.size(); ++i) differ += (near[i] != 0) != (other[i] != 0);
        EXPECT_EQ(differ, 0u) << name << (packets ? ", packets" : ", single rays") << ": "
                              << shadow_order_name(order) << " occlusion differs";
      }
    }
  }
}

TEST(StressRays, AxisParallelAndZeroComponentsAgreeWithBruteForce) {
  // Seed 43. Every direction has exact zeros (both +0 and -0: the sign picks the octant and
  // the inverse's infinity), so the slab and split-plane tests divide by zero.
  std::mt19937 rng(43);
  std::uniform_real_distribution<float> u(-2.5f, 2.5f), d(-1.0f, 1.0f);
  std::vector<RayQuery> rays;
  for (int i = 0; i < 6000; ++i) {
    RayQuery r;
    r.org = glm::vec3(u(rng), u(rng), u(rng));
    const int axis = i % 3;
    const float zero = (i / 3) % 2 ? -0.0f : 0.0f;
    r.dir = glm::vec3(zero);
    if ((i / 6) % 2 == 0) {
      r.dir[axis] = d(rng) < 0.0f ? -1.0f : 1.0f;  // along an axis
    } else {
      r.dir[axis] = d(rng);  // one exact zero component
      r.dir[(axis + 1) % 3] = d(rng);
    }
    if (r.dir == glm::vec3(0.0f)) r.dir[axis] = 1.0f;
    rays.push_back(r);
  }
  run(rays, "axis-parallel / zero components");
}

// A direction for a ray from an origin on a plane across axis `a`. `in_plane`: lying in the
// plane, +0 along the axis with `variant`, -0 without (a slab distance 0 * inf = NaN);
// otherwise along the axis with `variant`, else random (across the plane).
glm::vec3 plane_ray_dir(std::mt19937& rng, int a, bool in_plane, bool variant) {
  std::uniform_real_distribution<float> d(-1.0f, 1.0f);
  glm::vec3 dir(d(rng), d(rng), d(rng));
  if (in_plane) {
    dir[a] = variant ? 0.0f : -0.0f;
  } else if (variant) {
    dir = glm::vec3(0.0f);
    dir[a] = d(rng) < 0.0f ? -1.0f : 1.0f;
  }
  if (dir == glm::vec3(0.0f)) dir[(a + 1) % 3] = 1.0f;
  return dir;
}

// Origins exactly on each inner node's plane (inside the node's region or not). `in_plane`:
// directions lying in the plane (+0 or -0 along the axis: t_split = 0 * inf = NaN, the lane
// visits both children with its whole segment); otherwise across it or along the axis.
std::vector<RayQuery> split_plane_rays(std::uint32_t seed, bool in_plane) {
  const Fixture& f = fixture();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-2.2f, 2.2f);
  std::vector<RayQuery> rays;
  for (const KdNode& n : f.tree.nodes()) {
    if (n.is_leaf()) continue;
    const int a = n.axis();
    for (int kind = 0; kind < 2; ++kind) {
      RayQuery r;
      r.org = glm::vec3(u(rng), u(rng), u(rng));
      r.org[a] = n.split;
      r.dir = plane_ray_dir(rng, a, in_plane, kind == 0);
      rays.push_back(r);
    }
  }
  return rays;
}

TEST(StressRays, OriginsOnSplitPlanesCrossingThePlaneAgreeWithBruteForce) {
  run(split_plane_rays(47, false), "origins on split planes, crossing");  // seed 47
}

// Rays lying in a split plane get a NaN split distance and visit both children with the whole
// segment; the traversal used to drop the second child after a hit in the first (576 of 5630
// rays differed); it now decides per stacked subtree (tests/stress/README.md).
TEST(StressRays, OriginsOnSplitPlanesLyingInThePlaneAgreeWithBruteForce) {
  run(split_plane_rays(48, true), "origins on split planes, in the plane");  // seed 48
}

// The same on the faces of the leaf boxes (the tree with boxes everywhere): origins exactly on
// a face's plane, across it, along its axis or lying in it (0 * inf = NaN in the box's slab
// test, which must keep the lane).
std::vector<RayQuery> leaf_box_face_rays(std::uint32_t seed, bool in_plane) {
  const Fixture& f = fixture();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<RayQuery> rays;
  for (std::size_t i = 0; i < f.boxed.prim_refs().size(); ++i) {
    if (f.boxed.prim_refs()[i] != kLeafBoxRef) continue;
    const LeafBox& b = f.boxed.leaf_records()[i].box;
    const glm::vec3 lo(b.lo_x, b.lo_y, b.lo_z), hi(b.hi_x, b.hi_y, b.hi_z);
    const int a = static_cast<int>(rng() % 3);
    RayQuery r;
    // Mostly over the face, sometimes beside it.
    const glm::vec3 spread = (hi - lo) * 1.4f;
    r.org = lo - (hi - lo) * 0.2f + glm::vec3(u(rng) * spread.x, u(rng) * spread.y, u(rng) * spread.z);
    r.org[a] = rng() % 2 ? lo[a] : hi[a];
    const bool variant = rng() % 2;
    r.dir = plane_ray_dir(rng, a, in_plane, variant);
    rays.push_back(r);
  }
  return rays;
}

TEST(StressRays, OriginsOnLeafBoxFacesAgreeWithBruteForce) {
  run(leaf_box_face_rays(67, false), "origins on leaf box faces, crossing");  // seed 67
  run(leaf_box_face_rays(71, true), "origins on leaf box faces, in the plane");  // seed 71
}

TEST(StressRays, OriginsOnTriangleEdgesAndVerticesAgreeWithBruteForce) {
  // Seed 53. Origins at vertices and at points of edges (exact for the axis-aligned box edges),
  // leaving in random directions and along the triangle's own plane.
  const Fixture& f = fixture();
  std::mt19937 rng(53);
  std::uniform_real_distribution<float> u(0.0f, 1.0f), d(-1.0f, 1.0f);
  std::uniform_int_distribution<std::size_t> pick(0, f.soup.triangles.size() - 1);
  std::vector<RayQuery> rays;
  for (int i = 0; i < 12000; ++i) {
    const glm::uvec3 t = f.soup.triangles[pick(rng)];
    const glm::vec3 a = f.soup.positions[t.x], b = f.soup.positions[t.y], c = f.soup.positions[t.z];
    RayQuery r;
    r.org = i % 3 == 0 ? a : a + (b - a) * u(rng);
    if (i % 2 == 0) {
      r.dir = glm::vec3(d(rng), d(rng), d(rng));
    } else {
      r.dir = (c - r.org) + (b - a) * d(rng);  // in the plane, over the triangle
    }
    if (r.dir == glm::vec3(0.0f)) r.dir = glm::vec3(0.0f, 1.0f, 0.0f);
    rays.push_back(r);
  }
  run(rays, "origins on edges and vertices");
}

// The pop slack of the traversal (kd_traverse.h) brought the differences from 504 to 144 x 6;
// those left are the float test's rounding at the edges of neighbours the ray lies in or
// grazes (tests/stress/README.md), accepted only as such (EdgeRounding::Explained).
TEST(StressRays, RaysGrazingATrianglesPlaneAgreeWithBruteForce) {
  // Seed 59. From a point in a triangle's plane outside it, towards its centroid, tilted off
  // the plane by 0, 1e-7, 1e-5, 1e-3 of the direction's length (den ~ 0: t is huge or NaN).
  const Fixture& f = fixture();
  std::mt19937 rng(59);
  std::uniform_real_distribution<float> u(0.5f, 2.0f);
  std::uniform_int_distribution<std::size_t> pick(0, f.soup.triangles.size() - 1);
  std::vector<RayQuery> rays;
  for (int i = 0; i < 12000; ++i) {
    const glm::uvec3 t = f.soup.triangles[pick(rng)];
    const glm::vec3 a = f.soup.positions[t.x], b = f.soup.positions[t.y], c = f.soup.positions[t.z];
    const glm::vec3 centroid = (a + b + c) / 3.0f;
    const glm::vec3 n = glm::normalize(glm::cross(b - a, c - a));
    RayQuery r;
    r.org = centroid + (a - centroid) * (1.0f + u(rng));
    const glm::vec3 along = centroid - r.org;
    const float tilt[4] = {0.0f, 1e-7f, 1e-5f, 1e-3f};
    r.dir = along + n * (glm::length(along) * tilt[i % 4] * (i % 8 < 4 ? 1.0f : -1.0f));
    rays.push_back(r);
  }
  run(rays, "grazing rays", EdgeRounding::Explained);
}

TEST(StressRays, PacketsWithMixedDirectionSignsAgreeWithBruteForce) {
  // Seed 61. Consecutive rays form the packets: fully random directions (every lane its own
  // octant), coherent packets with one lane flipped, lanes differing only in the sign of a zero,
  // and lanes with different (t_min, t_max).
  const Fixture& f = fixture();
  std::mt19937 rng(61);
  std::uniform_real_distribution<float> d(-1.0f, 1.0f), u(0.0f, 1.0f);
  std::vector<RayQuery> rays = random_rays(61, 8000, f.box);
  for (int p = 0; p < 1000; ++p) {
    const glm::vec3 eye(d(rng) * 3.0f, d(rng) * 3.0f, 3.5f);
    const glm::vec3 dir = glm::normalize(glm::vec3(d(rng) * 0.3f, d(rng) * 0.3f, -1.0f));
    for (int lane = 0; lane < 16; ++lane) {
      RayQuery r;
      r.org = eye;
      r.dir = dir + glm::vec3(0.01f * static_cast<float>(lane % 4), 0.01f * static_cast<float>(lane / 4), 0.0f);
      switch (p % 4) {
        case 0:
          if (lane == 5) r.dir = -r.dir;  // one lane into the opposite octant
          break;
        case 1:
          r.dir.x = lane % 2 ? 0.0f : -0.0f;  // octants differing only in the sign of zero
          break;
        case 2:
          r.t_min = u(rng) * 3.0f;
          r.t_max = r.t_min + u(rng) * 4.0f;
          break;
        default:
          if (lane % 3 == 0) r.dir.y = -r.dir.y;
      }
      rays.push_back(r);
    }
  }
  run(rays, "mixed-sign packets");
}

}  // namespace
}  // namespace rtc::stress
