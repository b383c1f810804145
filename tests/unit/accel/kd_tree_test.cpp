// kd-tree build invariants, the triangle tests (Wald's and Woop's watertight one), and
// traversal against a brute-force double-precision reference, at packet width 4 and 1 (same
// bits).
#include <gtest/gtest.h>
#include <tbb/task_arena.h>
#include <xmmintrin.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <cstdio>
#include <limits>
#include <random>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "common/accel/kd_tree.h"
#include "common/accel/trace.h"
#include "common/base/isa.h"
#include "common/scene/tessellate.h"
#include "tests/support/hit_compare.h"
#include "tests/unit/accel/walk_order.h"

namespace rtc {
namespace {

struct Soup {
  std::vector<glm::vec3> positions;
  std::vector<glm::uvec3> triangles;
};

Soup random_soup(std::uint32_t seed, int count, float size) {
  SCOPED_TRACE("random_soup seed " + std::to_string(seed));
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> pos(-1.0f, 1.0f), off(-size, size);
  Soup s;
  for (int i = 0; i < count; ++i) {
    const glm::vec3 c(pos(rng), pos(rng), pos(rng));
    for (int k = 0; k < 3; ++k) s.positions.push_back(c + glm::vec3(off(rng), off(rng), off(rng)));
    const auto b = static_cast<unsigned>(3 * i);
    s.triangles.emplace_back(b, b + 1, b + 2);
  }
  return s;
}

// `copies` copies of one large triangle in the plane x = `x`, across y and z in [-1, 1].
void add_wall(Soup& s, float x, int copies) {
  const auto wall = static_cast<unsigned>(s.positions.size());
  s.positions.emplace_back(x, -1.0f, -1.0f);
  s.positions.emplace_back(x, 1.0f, -1.0f);
  s.positions.emplace_back(x, 0.0f, 1.0f);
  for (int i = 0; i < copies; ++i) s.triangles.emplace_back(wall, wall + 1, wall + 2);
}

// Two clusters of small random triangles, 35000 in x < -0.3 and 35000 in x > 0.3, and 30
// copies of one large triangle in the plane x = 0 between them. The binned root's best x plane
// is the copies' (they go to either side), and TopBuilder::refine's window around it holds only
// their 30 planar events, all equal (a window's events carry no reference): a list under 64 with
// equal keys, which a sort must keep whole.
Soup walled_gap() {
  Soup s;
  for (const float side : {-1.0f, 1.0f}) {
    Soup half = random_soup(side < 0.0f ? 41 : 43, 35000, 0.01f);
    const auto base = static_cast<unsigned>(s.positions.size());
    for (const glm::vec3& p : half.positions) s.positions.emplace_back(side * (0.65f + 0.35f * std::abs(p.x)), p.y, p.z);
    for (const glm::uvec3& t : half.triangles) s.triangles.emplace_back(t + glm::uvec3(base));
  }
  add_wall(s, 0.0f, 30);
  return s;
}

// Slivers from one vertex to random far points, each 1e-3 wide (Wald & Havran's case for
// clipping: their boxes cover most of the scene), plus the random soup of seed 5 among them.
Soup sliver_fan(std::uint32_t seed, int count) {
  SCOPED_TRACE("sliver_fan seed " + std::to_string(seed));
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> pos(-1.0f, 1.0f);
  Soup s = random_soup(5, 2000, 0.05f);
  const glm::vec3 hub(0.1f, -0.2f, 0.3f);
  for (int i = 0; i < count; ++i) {
    const glm::vec3 far(pos(rng), pos(rng), pos(rng));
    const auto b = static_cast<unsigned>(s.positions.size());
    s.positions.push_back(hub);
    s.positions.push_back(far);
    s.positions.push_back(far + glm::vec3(1e-3f, 0.0f, 1e-3f));
    s.triangles.emplace_back(b, b + 1, b + 2);
  }
  return s;
}

// A closed UV sphere plus an axis-aligned grid floor: shared edges, planar triangles lying in
// split planes, and axis-parallel faces.
Soup sphere_and_grid(int seg) {
  Soup s;
  const float pi = 3.14159265f;
  for (int i = 0; i <= seg; ++i) {
    for (int j = 0; j < 2 * seg; ++j) {
      const float th = pi * static_cast<float>(i) / static_cast<float>(seg);
      const float ph = pi * static_cast<float>(j) / static_cast<float>(seg);
      s.positions.emplace_back(std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph));
    }
  }
  const auto ring = static_cast<unsigned>(2 * seg);
  for (int i = 0; i < seg; ++i) {
    for (int j = 0; j < 2 * seg; ++j) {
      const unsigned a = static_cast<unsigned>(i) * ring + static_cast<unsigned>(j);
      const unsigned b = static_cast<unsigned>(i) * ring + (static_cast<unsigned>(j) + 1) % ring;
      const unsigned c = a + ring, d = b + ring;
      if (i > 0) s.triangles.emplace_back(a, b, c);
      if (i < seg - 1) s.triangles.emplace_back(b, d, c);
    }
  }
  const auto base = static_cast<unsigned>(s.positions.size());
  const int n = 8;
  for (int i = 0; i <= n; ++i) {
    for (int j = 0; j <= n; ++j) {
      s.positions.emplace_back(-2.0f + 0.5f * static_cast<float>(i), -1.0f, -2.0f + 0.5f * static_cast<float>(j));
    }
  }
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const unsigned a = base + static_cast<unsigned>(i * (n + 1) + j), b = a + 1,
                     c = a + static_cast<unsigned>(n + 1), d = c + 1;
      s.triangles.emplace_back(a, b, c);
      s.triangles.emplace_back(b, d, c);
    }
  }
  return s;
}

// Closed axis-aligned boxes apart from each other, 12 triangles each (`copies` times), every
// one lying in a plane of its box: the sweep cuts the empty space around a box at its faces,
// where those triangles lie, and with enough copies cuts a face's triangles off in a flat
// child on either side. So a cut's plane holds planar references, and the side they go to
// decides whether every reference is on one side (BlockBuilder's empty cuts).
Soup separate_boxes(std::uint32_t seed, int count, int copies) {
  SCOPED_TRACE("separate_boxes seed " + std::to_string(seed));
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> size(0.02f, 0.2f);
  Soup s;
  const int side = static_cast<int>(std::ceil(std::cbrt(static_cast<double>(count))));
  for (int i = 0; i < count; ++i) {
    const glm::vec3 lo(static_cast<float>(i % side), static_cast<float>(i / side % side),
                       static_cast<float>(i / (side * side)));
    const glm::vec3 hi = lo + glm::vec3(size(rng), size(rng), size(rng));
    const auto b = static_cast<unsigned>(s.positions.size());
    for (int k = 0; k < 8; ++k) s.positions.emplace_back(k & 1 ? hi.x : lo.x, k & 2 ? hi.y : lo.y, k & 4 ? hi.z : lo.z);
    // Two triangles per face: x = lo, x = hi, y = lo, y = hi, z = lo, z = hi.
    for (const glm::uvec4& f : {glm::uvec4(0, 2, 4, 6), glm::uvec4(1, 3, 5, 7), glm::uvec4(0, 1, 4, 5),
                                glm::uvec4(2, 3, 6, 7), glm::uvec4(0, 1, 2, 3), glm::uvec4(4, 5, 6, 7)}) {
      for (int c = 0; c < copies; ++c) {
        s.triangles.emplace_back(b + f.x, b + f.y, b + f.z);
        s.triangles.emplace_back(b + f.y, b + f.w, b + f.z);
      }
    }
  }
  return s;
}

// Ten small triangles in x < -0.8, 40 copies of one large triangle in the plane x = 0.3 and a
// thousand small ones in x > 0.5, all within y, z in [-1, 1]. The root cuts at x = 0.5, and its
// left child then at x = 0.3 with the copies going right, into the thin slab up to 0.5: the
// plane holds the node's last events, planar ones, and the left side still has references.
Soup pile_below_cut(std::uint32_t seed) {
  Soup s;
  const auto add_cluster = [&](std::uint32_t cluster_seed, int count, float x_lo, float x_hi) {
    std::mt19937 rng(cluster_seed);
    std::uniform_real_distribution<float> x(x_lo, x_hi), yz(-0.99f, 0.99f), off(-0.01f, 0.01f);
    for (int i = 0; i < count; ++i) {
      const glm::vec3 c(x(rng), yz(rng), yz(rng));
      const auto b = static_cast<unsigned>(s.positions.size());
      for (int k = 0; k < 3; ++k) {
        s.positions.push_back(glm::clamp(c + glm::vec3(off(rng), off(rng), off(rng)), glm::vec3(x_lo, -1.0f, -1.0f),
                                         glm::vec3(x_hi, 1.0f, 1.0f)));
      }
      s.triangles.emplace_back(b, b + 1, b + 2);
    }
  };
  add_cluster(seed, 10, -1.0f, -0.8f);
  add_cluster(seed + 1, 1000, 0.5f, 1.0f);
  add_wall(s, 0.3f, 40);
  return s;
}

// Two slabs of 1000 triangles each, x in [0, 0.1] and [0.9, 1] with y and z in [0, 1] (one
// triangle in each spans its slab's box, so the bounds are exact; the first slab also holds
// one lying in the plane y = 1), and one thin triangle at x = 5 up to y = 1.1. The root cuts
// the thin one off at x = 1; its left child's cell is then [0, 1] x [0, 1.1] x [0, 1], with the
// slabs leaving a gap of 0.1 / 1.1 = 0.09 of y above them. There the SAH prefers a plane
// between the slabs (x = 0.1) to cutting off that gap. A cut at y = 1 is one-sided only if the
// planar triangle there goes below it, with the rest.
Soup slabs_under_gap() {
  Soup s;
  const auto add = [&](glm::vec3 a, glm::vec3 b, glm::vec3 c) {
    const auto first = static_cast<unsigned>(s.positions.size());
    s.positions.insert(s.positions.end(), {a, b, c});
    s.triangles.emplace_back(first, first + 1, first + 2);
  };
  const auto add_slab = [&](std::uint32_t seed, float x_lo) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> x(x_lo, x_lo + 0.1f), yz(0.0f, 1.0f);
    const std::size_t end = s.triangles.size() + 1000;
    add({x_lo, 0.0f, 0.0f}, {x_lo + 0.1f, 1.0f, 0.0f}, {x_lo, 0.0f, 1.0f});
    if (x_lo == 0.0f) add({0.0f, 1.0f, 0.0f}, {0.1f, 1.0f, 0.0f}, {0.0f, 1.0f, 1.0f});
    while (s.triangles.size() < end) {
      // Braces fix the draws' order: vertex by vertex, x, y, z.
      glm::vec3 v[3];
      for (glm::vec3& p : v) p = {x(rng), yz(rng), yz(rng)};
      add(v[0], v[1], v[2]);
    }
  };
  add_slab(71, 0.0f);
  add_slab(73, 0.9f);
  add({5.0f, 0.0f, 0.0f}, {5.1f, 1.1f, 0.0f}, {5.0f, 0.0f, 1.0f});
  return s;
}

std::vector<std::uint32_t> refs_of(const KdTree& tree) { return {tree.prim_refs().begin(), tree.prim_refs().end()}; }

bool leaf_has(const KdTree& tree, const KdNode& leaf, std::uint32_t tri) {
  const TriRecord* r = tree.leaf_records().data() + leaf.prim_offset();
  return std::any_of(r, r + leaf.tri_count(), [&](const TriRecord& rec) { return rec.wald.id == tri; });
}

// Bounds of the triangle clipped to `box` in double (Sutherland-Hodgman; a point on a plane
// is inside); empty where the triangle misses the box.
std::pair<glm::dvec3, glm::dvec3> clip_to_box(const Soup& s, std::uint32_t t, const Aabb& box) {
  std::vector<glm::dvec3> poly, next;
  for (int k = 0; k < 3; ++k) poly.emplace_back(s.positions[s.triangles[t][k]]);
  for (int plane = 0; plane < 6 && !poly.empty(); ++plane) {
    const int axis = plane >> 1;
    const bool upper = plane & 1;
    const double bound = upper ? box.hi[axis] : box.lo[axis];
    auto inside = [&](const glm::dvec3& v) { return upper ? v[axis] <= bound : v[axis] >= bound; };
    next.clear();
    for (std::size_t i = 0; i < poly.size(); ++i) {
      const glm::dvec3 a = poly[i], b = poly[(i + 1) % poly.size()];
      if (inside(a)) next.push_back(a);
      if (inside(a) != inside(b)) {
        glm::dvec3 x = a + (bound - a[axis]) / (b[axis] - a[axis]) * (b - a);
        x[axis] = bound;
        next.push_back(x);
      }
    }
    poly.swap(next);
  }
  glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
  for (const glm::dvec3& v : poly) {
    lo = glm::min(lo, v);
    hi = glm::max(hi, v);
  }
  return {lo, hi};
}

// Every triangle is referenced by every leaf its clipped geometry overlaps with positive
// extent along the split (beyond a relative 1e-9, far above the clip's double rounding and far
// below float spacing); a triangle lying in a split plane by at least one side. The build
// clips straddling triangles to each child ("perfect splits"), so bounding boxes would ask
// too much.
bool reachable(const KdTree& tree, const Soup& s, std::uint32_t index, const Aabb& box, std::uint32_t tri) {
  const auto [lo, hi] = clip_to_box(s, tri, box);
  if (lo.x > hi.x) return true;  // not in this node
  const KdNode& node = tree.nodes()[index];
  if (node.is_leaf()) return leaf_has(tree, node, tri);
  const int a = node.axis();
  const double p = node.split;
  const double tol = 1e-9 * std::max(1.0, std::abs(p));
  Aabb left = box, right = box;
  left.hi[a] = node.split;
  right.lo[a] = node.split;
  if (lo[a] >= p - tol && hi[a] <= p + tol) {
    return reachable(tree, s, node.left(), left, tri) || reachable(tree, s, node.left() + 1, right, tri);
  }
  bool ok = true;
  if (lo[a] < p - tol) ok = ok && reachable(tree, s, node.left(), left, tri);
  if (hi[a] > p + tol) ok = ok && reachable(tree, s, node.left() + 1, right, tri);
  return ok;
}

TEST(KdTree, EveryTriangleReachableFromTheLeavesItOverlaps) {
  // Seeds 7 and 11 (random soups), then a sphere on a grid, then slivers the build clips, then
  // boxes and a pile of planar triangles whose planes the sweep cuts at (empty cuts and not).
  for (const Soup& s :
       {random_soup(7, 5000, 0.05f), sphere_and_grid(24), random_soup(11, 300, 0.8f), sliver_fan(13, 3000),
        separate_boxes(47, 400, 1), pile_below_cut(61)}) {
    // The bit-mask stage from 256 references (four words), 130 (three), 64 (one), 17, and not
    // at all; empty gaps cut at once from 0 of the cell (any gap), 0.3, or never.
    for (const auto& [clip, mask_below, empty_cut] :
         {std::tuple{true, 256, 0.0f}, std::tuple{true, 130, 2.0f}, std::tuple{true, 64, 0.3f},
          std::tuple{true, 17, 0.0f}, std::tuple{true, 0, 2.0f}, std::tuple{true, 0, 0.0f},
          std::tuple{false, 256, 0.3f}, std::tuple{false, 64, 2.0f}, std::tuple{false, 0, 0.0f}}) {
      KdBuildOptions o;
      o.clip = clip;
      o.mask_below = mask_below;
      o.empty_cut = empty_cut;
      const KdTree tree = KdTree::build(s.positions, s.triangles, o);
      ASSERT_FALSE(tree.empty());
      EXPECT_GT(tree.stats().leaves, 1u);
      const Aabb root = [&] {
        Aabb b;
        for (const glm::vec3& v : s.positions) b.extend(v);
        return b;
      }();
      for (std::uint32_t t = 0; t < s.triangles.size(); ++t) {
        ASSERT_TRUE(reachable(tree, s, 0, root, t))
            << "triangle " << t << " unreachable, clip " << clip << ", mask below " << mask_below << ", empty cut "
            << empty_cut;
      }
    }
  }
}

TEST(KdTree, LargeArraysAreAlignedToHugePages) {
  for (const std::size_t bytes : {std::size_t{48}, std::size_t{1} << 20, (std::size_t{2} << 20) - 16,
                                  std::size_t{2} << 20, (std::size_t{3} << 20) + 48}) {
    void* p = alloc_pages(bytes, 16);
    ASSERT_NE(p, nullptr);
    const std::size_t align = bytes >= (std::size_t{2} << 20) ? std::size_t{2} << 20 : 16;
    EXPECT_EQ(reinterpret_cast<std::uintptr_t>(p) % align, 0u) << bytes << " bytes";
    std::memset(p, 0xAB, bytes);  // every byte asked for is there
    EXPECT_EQ(static_cast<unsigned char*>(p)[bytes - 1], 0xABu);
    free_pages(p, bytes, 16);
  }
  RawArray<TriRecord> records(100000);  // 4.8 MB
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(records.data()) % (std::size_t{2} << 20), 0u);
  EXPECT_EQ(records.size(), 100000u);
}

TEST(KdTree, NodesAreEightBytesWithAdjacentChildren) {
  const Soup s = sphere_and_grid(16);
  const KdTree tree = KdTree::build(s.positions, s.triangles);
  for (const KdNode& n : tree.nodes()) {
    if (n.is_leaf()) {
      EXPECT_LE(n.prim_offset() + n.tri_count(), tree.prim_refs().size());
    } else {
      EXPECT_LT(n.left() + 1, tree.nodes().size());
      EXPECT_LT(n.axis(), 3);
    }
  }
  EXPECT_EQ(tree.stats().nodes, tree.nodes().size());
  EXPECT_GT(tree.stats().sah_cost, 0.0);
  EXPECT_EQ(tree.stats().bytes, tree.nodes().size() * 8 + tree.prim_refs().size() * (4 + 48));
  EXPECT_EQ(tree.stats().prim_refs + tree.stats().leaf_boxes, tree.prim_refs().size());
  // The traversal reads a leaf's records in sequence from leaf_records(): each is its
  // reference's triangle's record, every byte of it (the padding zero), or a LeafBox.
  ASSERT_EQ(tree.leaf_records().size(), tree.prim_refs().size());
  for (std::size_t i = 0; i < tree.prim_refs().size(); ++i) {
    const std::uint32_t index = tree.prim_refs()[i];
    if (index == kLeafBoxRef) {
      EXPECT_EQ(tree.leaf_records()[i].wald.k, 3u);
      EXPECT_EQ(tree.leaf_records()[i].wald.id, kLeafBoxRef);
      continue;
    }
    const glm::uvec3 t = s.triangles[index];
    TriRecord expected{};
    expected.wald = make_tri_accel(s.positions[t.x], s.positions[t.y], s.positions[t.z]);
    expected.wald.id = index;
    ASSERT_LT(expected.wald.k, 3u) << "reference " << i << ": a degenerate triangle in a leaf";
    ASSERT_EQ(std::memcmp(&tree.leaf_records()[i], &expected, sizeof(TriRecord)), 0) << "reference " << i;
  }
}

// A leaf's box (KdBuildOptions::leaf_box_saving): the slot before its first reference, and it
// holds every part of the leaf's triangles inside the leaf's cell, or the walks would lose hits
// there. Checked with a box on nearly every leaf, with and without clipping, in the event
// sweep, the bit-mask stage and a bit-mask stage taking every node.
void check_leaf_boxes(const KdTree& tree, const Soup& s, std::uint32_t index, const Aabb& cell, double pad,
                      std::size_t& boxed, std::size_t& slots) {
  const KdNode& node = tree.nodes()[index];
  if (!node.is_leaf()) {
    Aabb left = cell, right = cell;
    left.hi[node.axis()] = node.split;
    right.lo[node.axis()] = node.split;
    check_leaf_boxes(tree, s, node.left(), left, pad, boxed, slots);
    check_leaf_boxes(tree, s, node.left() + 1, right, pad, boxed, slots);
    return;
  }
  const std::uint32_t first = node.prim_offset(), count = node.tri_count();
  for (std::uint32_t i = 0; i < count; ++i) ASSERT_NE(tree.prim_refs()[first + i], kLeafBoxRef);
  if (!node.has_box()) return;
  ++boxed;
  ASSERT_GT(count, 0u);
  ASSERT_GE(first, 1u);
  ASSERT_EQ(tree.prim_refs()[first - 1], kLeafBoxRef);
  ++slots;
  // The box as the build made it, before its widening by `pad` (the float subtraction of pad
  // rounded by up to an ulp, so a tolerance of two).
  const LeafBox& b = tree.leaf_records()[first - 1].box;
  const glm::dvec3 lo = glm::dvec3(b.lo_x, b.lo_y, b.lo_z) + pad, hi = glm::dvec3(b.hi_x, b.hi_y, b.hi_z) - pad;
  for (std::uint32_t i = 0; i < count; ++i) {
    const std::uint32_t tri = tree.prim_refs()[first + i];
    const auto [tlo, thi] = clip_to_box(s, tri, cell);
    if (tlo.x > thi.x) continue;  // a reference the bit-mask stage kept without clipping
    for (int a = 0; a < 3; ++a) {
      const double tol = 0x1p-22 * std::max({1.0, std::abs(tlo[a]), std::abs(thi[a])});
      ASSERT_LE(lo[a], tlo[a] + tol) << "triangle " << tri << " sticks out of its leaf's box, axis " << a;
      ASSERT_GE(hi[a], thi[a] - tol) << "triangle " << tri << " sticks out of its leaf's box, axis " << a;
    }
  }
}

TEST(KdTree, LeafBoxesHoldTheirTrianglesInTheCell) {
  for (const Soup& s : {sphere_and_grid(24), random_soup(7, 5000, 0.05f), sliver_fan(13, 3000), walled_gap()}) {
    for (const auto& [clip, mask_below] : {std::pair{true, -1}, std::pair{true, 0}, std::pair{false, -1}}) {
      KdBuildOptions o;
      o.clip = clip;
      o.mask_below = mask_below;
      o.leaf_box_saving = 1e-6f;  // a box wherever the content is smaller than the cell
      const KdTree tree = KdTree::build(s.positions, s.triangles, o);
      // The widening: 2^-18 of the largest coordinate of the triangles' bounds.
      Aabb root;
      for (const glm::uvec3& t : s.triangles) {
        for (int k = 0; k < 3; ++k) root.extend(s.positions[t[k]]);
      }
      const glm::vec3 mag = glm::max(glm::abs(root.lo), glm::abs(root.hi));
      const double pad = static_cast<double>(std::max({mag.x, mag.y, mag.z}) * 0x1p-18f);
      std::size_t boxed = 0, slots = 0;
      check_leaf_boxes(tree, s, 0, tree.bounds(), pad, boxed, slots);
      EXPECT_GT(boxed, 0u) << "clip " << clip << ", mask below " << mask_below;
      EXPECT_EQ(boxed, tree.stats().leaf_boxes);
      EXPECT_EQ(slots, static_cast<std::size_t>(
                           std::count(tree.prim_refs().begin(), tree.prim_refs().end(), kLeafBoxRef)));
      // The same leaves and triangles as without boxes.
      o.leaf_box_saving = 0.0f;
      const KdTree plain = KdTree::build(s.positions, s.triangles, o);
      EXPECT_EQ(plain.stats().leaf_boxes, 0u);
      EXPECT_EQ(plain.stats().prim_refs, tree.stats().prim_refs);
      std::vector<std::uint32_t> refs = refs_of(tree);
      refs.erase(std::remove(refs.begin(), refs.end(), kLeafBoxRef), refs.end());
      EXPECT_EQ(refs, refs_of(plain));
      ASSERT_EQ(plain.nodes().size(), tree.nodes().size());
      for (std::size_t i = 0; i < tree.nodes().size(); ++i) {
        ASSERT_EQ(plain.nodes()[i].is_leaf(), tree.nodes()[i].is_leaf());
        if (tree.nodes()[i].is_leaf()) {
          ASSERT_EQ(plain.nodes()[i].tri_count(), tree.nodes()[i].tri_count());
        }
      }
    }
  }
}

void check_saving(const KdTree& tree, std::uint32_t index, const Aabb& cell, float saving) {
  const KdNode& node = tree.nodes()[index];
  if (!node.is_leaf()) {
    Aabb left = cell, right = cell;
    left.hi[node.axis()] = node.split;
    right.lo[node.axis()] = node.split;
    check_saving(tree, node.left(), left, saving);
    check_saving(tree, node.left() + 1, right, saving);
    return;
  }
  if (!node.has_box()) return;
  const LeafBox& b = tree.leaf_records()[node.prim_offset() - 1].box;
  Aabb box;
  box.extend(glm::vec3(b.lo_x, b.lo_y, b.lo_z));
  box.extend(glm::vec3(b.hi_x, b.hi_y, b.hi_z));
  const double miss = 1.0 - std::min(1.0, static_cast<double>(box.area()) / static_cast<double>(cell.area()));
  EXPECT_GE(node.tri_count() * miss, saving * 0.99) << "a leaf of " << node.tri_count() << " triangles";
}

// Boxes go where the SAH's estimate of the tests they save reaches leaf_box_saving: more of
// them at a lower threshold, none at 0.
TEST(KdTree, LeafBoxesFollowTheirSavingThreshold) {
  const Soup s = sphere_and_grid(24);
  std::vector<std::uint64_t> boxes;
  for (const float saving : {1e-6f, 1.0f, 2.0f, 8.0f, 0.0f}) {
    KdBuildOptions o;
    o.leaf_box_saving = saving;
    const KdTree tree = KdTree::build(s.positions, s.triangles, o);
    boxes.push_back(tree.stats().leaf_boxes);
    // Every boxed leaf meets the threshold by the box it holds: count x (1 - area(box) /
    // area(cell)) >= saving, within 1% (the stored box is a little wider than the build's,
    // which at a threshold of 1e-6 is all there is to it).
    if (saving >= 1.0f) check_saving(tree, 0, tree.bounds(), saving);
  }
  EXPECT_GT(boxes[0], boxes[3]);
  for (std::size_t i = 1; i < boxes.size(); ++i) EXPECT_LE(boxes[i], boxes[i - 1]) << "threshold " << i;
  std::printf("leaf boxes at thresholds 1e-6, 1, 2, 8, 0: %llu %llu %llu %llu %llu\n",
              static_cast<unsigned long long>(boxes[0]), static_cast<unsigned long long>(boxes[1]),
              static_cast<unsigned long long>(boxes[2]), static_cast<unsigned long long>(boxes[3]),
              static_cast<unsigned long long>(boxes[4]));
  EXPECT_GT(boxes[1], 0u);  // the threshold check above has leaves to check
  EXPECT_EQ(boxes[4], 0u);
}

// The traversal passes by a child marked empty without loading it, so a mark on a child with
// triangles would lose hits, and a missing mark costs a visit. Every inner node's marks must
// say exactly which of its children are empty leaves: in the binned top levels (walled_gap's
// 70,000 triangles reach them), the event sweep and the bit-mask stage below them.
TEST(KdTree, InnerNodesMarkExactlyTheirEmptyChildren) {
  for (const Soup& s : {walled_gap(), sphere_and_grid(24), random_soup(7, 5000, 0.05f)}) {
    for (int mask_below : {0, -1}) {
      KdBuildOptions options;
      options.mask_below = mask_below;
      const KdTree tree = KdTree::build(s.positions, s.triangles, options);
      std::size_t marked = 0, unmarked_leaves = 0;
      for (std::size_t i = 0; i < tree.nodes().size(); ++i) {
        const KdNode& n = tree.nodes()[i];
        if (n.is_leaf()) continue;
        for (std::uint32_t c = 0; c < 2; ++c) {
          const KdNode& child = tree.nodes()[n.left() + c];
          const bool empty = child.is_empty_leaf();
          ASSERT_EQ(n.child_empty(c), empty) << "node " << i << ", child " << c;
          marked += empty ? 1 : 0;
          unmarked_leaves += child.is_leaf() && !empty ? 1 : 0;
        }
      }
      EXPECT_EQ(marked, tree.stats().empty_leaves);
      EXPECT_GT(marked, 0u);
      EXPECT_GT(unmarked_leaves, 0u);
    }
  }
}

TEST(KdTree, BuildIsIndependentOfThreadCount) {
  const Soup s = random_soup(3, 70000, 0.02f);  // above the parallel big-node threshold
  for (bool clip : {true, false}) {
  KdBuildOptions one;
  one.threads = 1;
  one.clip = clip;
  KdBuildOptions two = one;
  two.threads = 2;
  const KdTree a = KdTree::build(s.positions, s.triangles, one);
  const KdTree b = KdTree::build(s.positions, s.triangles, two);
  ASSERT_EQ(a.nodes().size(), b.nodes().size());
  ASSERT_EQ(refs_of(a), refs_of(b));
  for (std::size_t i = 0; i < a.nodes().size(); ++i) {
    ASSERT_EQ(a.nodes()[i].bits, b.nodes()[i].bits);
    ASSERT_EQ(a.nodes()[i].count, b.nodes()[i].count);
  }
  }
}

// Coincident and axis-aligned triangles in piles: many events at one position, planar ones
// among them (the ties the sweep settles by order of positions, axes and sides), with -0 for
// every other triangle's zero coordinates (+0 and -0 in one group of equal positions).
Soup planar_piles(std::uint32_t seed, int count) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> cell(-4, 4), axis(0, 2);
  Soup s;
  for (int i = 0; i < count; ++i) {
    glm::vec3 c(0.25f * static_cast<float>(cell(rng)), 0.25f * static_cast<float>(cell(rng)),
                0.25f * static_cast<float>(cell(rng)));
    for (int j = 0; j < 3; ++j) {
      if (c[j] == 0.0f && (i & 1)) c[j] = -0.0f;
    }
    const int k = axis(rng);  // the triangle lies in the plane x_k = c_k
    glm::vec3 e1(0.0f), e2(0.0f);
    e1[(k + 1) % 3] = 0.25f;
    e2[(k + 2) % 3] = 0.25f;
    const auto b = static_cast<unsigned>(s.positions.size());
    s.positions.push_back(c);
    s.positions.push_back(c + e1);
    s.positions.push_back(c + e2);
    s.triangles.emplace_back(b, b + 1, b + 2);
  }
  return s;
}

// Eight cells along y, each with a triangle left of x = 0, one right of it and one in the plane
// x = 0 between them: +0 in the first four cells, -0 in the others. At K_T = 0.1 the cells split
// first, then each cell at x = 0, where the upper cells' nodes see only -0 (the whole soup's
// first event at zero is +0): without events written as +0 the planes there came out -0 from
// the sweep and +0 from the masks.
Soup signed_zero_cells() {
  Soup s;
  for (int j = 0; j < 8; ++j) {
    const float y = 10.0f * static_cast<float>(j);
    const float zero = j < 4 ? 0.0f : -0.0f;
    for (const float x : {-1.0f, zero, 1.0f}) {
      const auto b = static_cast<unsigned>(s.positions.size());
      const float w = x == 0.0f ? 0.0f : 0.2f;  // the middle one lies in x = 0
      s.positions.emplace_back(x, y, 0.0f);
      s.positions.emplace_back(x + w, y + 1.0f, 0.0f);
      s.positions.emplace_back(x, y, 1.0f);
      s.triangles.emplace_back(b, b + 1, b + 2);
    }
  }
  return s;
}

// The same nodes, references, leaf records and statistics, bit for bit (`same_sum`: the SAH
// cost too; else within 4 ulps, for trees whose cost terms were added up in another grouping).
void expect_same_tree(const KdTree& x, const KdTree& y, bool same_sum = true) {
  ASSERT_EQ(x.nodes().size(), y.nodes().size());
  for (std::size_t i = 0; i < x.nodes().size(); ++i) {
    ASSERT_EQ(x.nodes()[i].bits, y.nodes()[i].bits) << "node " << i;
    ASSERT_EQ(x.nodes()[i].count, y.nodes()[i].count) << "node " << i;
  }
  ASSERT_EQ(refs_of(x), refs_of(y));
  ASSERT_EQ(x.leaf_records().size(), y.leaf_records().size());
  EXPECT_EQ(std::memcmp(x.leaf_records().data(), y.leaf_records().data(), x.leaf_records().size_bytes()), 0);
  if (same_sum) {
    EXPECT_EQ(x.stats().sah_cost, y.stats().sah_cost);
  } else {
    EXPECT_DOUBLE_EQ(x.stats().sah_cost, y.stats().sah_cost);
  }
  EXPECT_EQ(x.stats().leaves, y.stats().leaves);
  EXPECT_EQ(x.stats().empty_leaves, y.stats().empty_leaves);
  EXPECT_EQ(x.stats().leaf_boxes, y.stats().leaf_boxes);
  EXPECT_EQ(x.stats().max_depth, y.stats().max_depth);
}

// The build keeps its scratch buffers from one build to the next (ScratchPool): a tree built
// after other builds have used and left them behind is the tree built before them.
TEST(KdTree, BuffersKeptFromEarlierBuildsChangeNoTree) {
  const Soup a = random_soup(11, 3000, 0.05f);  // two blocks (binned_root_above)
  for (const bool clip : {true, false}) {
    SCOPED_TRACE(testing::Message() << "clip " << clip);
    KdBuildOptions o;
    o.clip = clip;
    o.threads = 2;
    const KdTree first = KdTree::build(a.positions, a.triangles, o);
    // Other builds in between leave bigger lists, masks of every width and stacks behind.
    const Soup piles = planar_piles(12, 5000);
    const Soup big = random_soup(13, 20000, 0.02f);
    for (const int mask_below : {0, 64, 256}) {
      KdBuildOptions other = o;
      other.mask_below = mask_below;
      (void)KdTree::build(piles.positions, piles.triangles, other);
      (void)KdTree::build(big.positions, big.triangles, other);
    }
    const KdTree again = KdTree::build(a.positions, a.triangles, o);
    expect_same_tree(first, again);
  }
}

// A freed tree's arrays of 2 MiB or more are kept and lent again (free_pages): a tree built in
// the memory another, different tree left behind is, byte for byte, the tree built in memory
// the cache did not supply, so the build writes every byte it keeps.
TEST(KdTree, ArraysKeptFromFreedTreesChangeNoTree) {
  const Soup a = random_soup(31, 70000, 0.02f);
  const Soup b = random_soup(32, 60000, 0.02f);
  for (const bool clip : {true, false}) {
    SCOPED_TRACE(testing::Message() << "clip " << clip);
    KdBuildOptions o;
    o.clip = clip;
    release_page_cache();
    const KdTree fresh = KdTree::build(b.positions, b.triangles, o);
    ASSERT_GE(fresh.leaf_records().size_bytes(), std::size_t{2} << 20);
    {
      const KdTree other = KdTree::build(a.positions, a.triangles, o);
      ASSERT_GE(other.leaf_records().size_bytes(), fresh.leaf_records().size_bytes());
    }
    const PageCacheStats kept = page_cache_stats();
    EXPECT_GE(kept.blocks, 2u);  // at least its records and its references
    const KdTree again = KdTree::build(b.positions, b.triangles, o);
    EXPECT_GE(page_cache_stats().reused, kept.reused + 2);
    expect_same_tree(fresh, again);
  }
  release_page_cache();
  EXPECT_EQ(page_cache_stats().blocks, 0u);
  EXPECT_EQ(page_cache_stats().bytes, 0u);
}

// free_pages keeps blocks of 2 MiB and more, up to kPageCacheBlocks and kPageCacheBytes (the
// oldest freed first beyond them), and lends one again for a request of at least half its size.
TEST(KdTree, PageCacheKeepsWithinItsLimits) {
  constexpr std::size_t kMiB = std::size_t{1} << 20;
  release_page_cache();
  void* small = alloc_pages(kMiB, 16);
  free_pages(small, kMiB, 16);
  EXPECT_EQ(page_cache_stats().blocks, 0u);  // malloc's
  std::vector<void*> blocks;
  for (std::size_t i = 0; i < kPageCacheBlocks + 2; ++i) blocks.push_back(alloc_pages(2 * kMiB, 16));
  for (void* p : blocks) free_pages(p, 2 * kMiB, 16);
  EXPECT_EQ(page_cache_stats().blocks, kPageCacheBlocks);
  EXPECT_EQ(page_cache_stats().bytes, kPageCacheBlocks * 2 * kMiB);
  release_page_cache();

  void* big = alloc_pages(8 * kMiB, 16);
  free_pages(big, 8 * kMiB, 16);
  const std::uint64_t reused = page_cache_stats().reused;
  void* quarter = alloc_pages(2 * kMiB, 16);  // 8 MiB is more than twice this: a new block
  EXPECT_NE(quarter, big);
  EXPECT_EQ(page_cache_stats().reused, reused);
  void* most = alloc_pages(5 * kMiB, 16);  // 6 MiB rounded: the 8 MiB block
  EXPECT_EQ(most, big);
  EXPECT_EQ(page_cache_stats().reused, reused + 1);
  free_pages(quarter, 2 * kMiB, 16);
  free_pages(most, 5 * kMiB, 16);  // comes back as the 8 MiB it is
  EXPECT_EQ(page_cache_stats().bytes, 10 * kMiB);
  release_page_cache();

  // Two blocks of 600 MiB (address space only: never touched) are more than kPageCacheBytes
  // together: the older one is freed.
  static_assert(kPageCacheBytes < 1200 * kMiB && kPageCacheBytes >= 600 * kMiB);
  void* first = alloc_pages(600 * kMiB, 16);
  void* second = alloc_pages(600 * kMiB, 16);
  free_pages(first, 600 * kMiB, 16);
  free_pages(second, 600 * kMiB, 16);
  EXPECT_EQ(page_cache_stats().blocks, 1u);
  EXPECT_EQ(page_cache_stats().bytes, 600 * kMiB);
  void* again = alloc_pages(600 * kMiB, 16);
  EXPECT_EQ(again, second);
  free_pages(again, 600 * kMiB, 16);
  release_page_cache();
}

// With more than one thread, a block's large nodes' children are built as tasks of their own
// (BlockBuilder::fork) and spliced back in wherever a thread has nothing else to do: from a
// small scene's root (one block of the exact stage, with binned_root_above off here), and in a
// larger scene's last blocks. A
// small scene's block also makes its three event lists and its large nodes' three sweeps side
// by side (kSideBySideSetUp: the two one-block soups here are above it). The tree, its records
// and every statistic (the SAH cost's float sum too) are those one thread makes.
TEST(KdTree, BlocksForkedAcrossThreadsBuildTheOneThreadTree) {
  // One block each (the root not binned), except the last: a few blocks (whether one forks
  // depends on when the others end).
  const Soup soups[] = {random_soup(21, 3500, 0.05f), planar_piles(22, 3000), random_soup(23, 12000, 0.01f)};
  for (const Soup& s : soups) {
    const bool one_block = s.triangles.size() <= 4096;
    for (const bool clip : {true, false}) {
      SCOPED_TRACE(testing::Message() << s.triangles.size() << " triangles, clip " << clip);
      KdBuildOptions one;
      one.clip = clip;
      one.binned_root_above = 4096;  // off: a soup of at most 4096 triangles is one block
      one.threads = 1;
      KdBuildOptions two = one;
      two.threads = 2;
      const KdTree a = KdTree::build(s.positions, s.triangles, one);
      const KdTree b = KdTree::build(s.positions, s.triangles, two);
      EXPECT_EQ(a.stats().forks, 0u);
      if (one_block && tbb::this_task_arena::max_concurrency() >= 2) {  // the threads TBB may use here
        EXPECT_GT(b.stats().forks, 0u);
      }
      expect_same_tree(a, b);
    }
  }
}

TEST(KdTree, BinnedRootSplitsAOneBlockSceneIntoTwo) {
  // KdBuildOptions::binned_root_above: a scene of at most exact_below triangles but more than
  // binned_root_above has its root split by the binned SAH, refined to the exact plane near the
  // best bin (of each axis within 1% of the best), and builds as two blocks (side by side at
  // 2 threads); the same tree at 1 and 2 threads. On the first three soups (and the shared
  // scenes of 1,025-4,096 triangles) the refined plane is the exact sweep's own, so the tree is
  // the one block's, node for node (its SAH cost terms summed in another grouping). The planar
  // piles and the sphere fail without the axes near the best refined too, or with the refined
  // plane's -0 left as it is (the sweep writes +0). Without the refinement a bin boundary stood
  // in for the plane (bunny: SAH cost 107.36 -> 107.53). The slivers' exact root plane lies
  // outside the windows: another plane, whose tree's SAH cost is within 0.001% of the one
  // block's (asserted: within 0.1%).
  EXPECT_EQ(KdBuildOptions{}.binned_root_above, 1024);  // the default bins such a root
  const std::pair<Soup, bool> soups[] = {{random_soup(21, 3500, 0.05f), true},
                                         {planar_piles(22, 3000), true},
                                         {sphere_and_grid(24), true},
                                         {sliver_fan(13, 2000), false}};
  for (const auto& [s, one_blocks_tree] : soups) {
    ASSERT_GT(s.triangles.size(), 1024u);
    ASSERT_LE(s.triangles.size(), 4096u);
    for (const bool clip : {true, false}) {
      SCOPED_TRACE(testing::Message() << s.triangles.size() << " triangles, clip " << clip);
      KdBuildOptions block;
      block.clip = clip;
      block.binned_root_above = 4096;
      block.threads = 1;
      KdBuildOptions binned = block;
      binned.binned_root_above = 1024;
      KdBuildOptions binned2 = binned;
      binned2.threads = 2;
      const KdTree a = KdTree::build(s.positions, s.triangles, block);
      const KdTree b = KdTree::build(s.positions, s.triangles, binned);
      const KdTree c = KdTree::build(s.positions, s.triangles, binned2);
      EXPECT_EQ(a.stats().blocks, 1u);
      EXPECT_EQ(b.stats().blocks, 2u);
      EXPECT_EQ(c.stats().blocks, 2u);
      expect_same_tree(b, c);
      // The SAH cost within 0.1% of the one block's: the refined root plane is one of the best.
      EXPECT_LE(b.stats().sah_cost, a.stats().sah_cost * 1.001);
      if (one_blocks_tree) expect_same_tree(a, b, false);
    }
  }
  // 1,024 references: one block; 1,025: two. A value of exact_below or more is off.
  KdBuildOptions defaults;
  const Soup at = random_soup(25, 1024, 0.05f), above = random_soup(25, 1025, 0.05f);
  EXPECT_EQ(KdTree::build(at.positions, at.triangles, defaults).stats().blocks, 1u);
  EXPECT_EQ(KdTree::build(above.positions, above.triangles, defaults).stats().blocks, 2u);
  KdBuildOptions off;
  off.binned_root_above = 1 << 30;
  EXPECT_EQ(KdTree::build(above.positions, above.triangles, off).stats().blocks, 1u);
  // Above exact_below the root was binned before: the same tree whatever binned_root_above.
  const Soup large = random_soup(23, 12000, 0.01f);
  const KdTree large_default = KdTree::build(large.positions, large.triangles, defaults);
  EXPECT_GT(large_default.stats().blocks, 2u);
  expect_same_tree(large_default, KdTree::build(large.positions, large.triangles, off));
}

TEST(KdTree, BitMaskStageBuildsTheEventSweepsTreeWithoutClipping) {
  // Without clipping the bit masks are the event sweep by other means: the same planes, counts,
  // costs and ties, so node for node the same tree.
  // Soup 19 has 64 triangles, so its root is one full 64-bit mask; soups 23 and 31 have 128 and
  // 256, two and four full words; soup 37 has 150, three words, the last partly used. In
  // walled_gap a node of the 30 coincident wall triangles alone splits at their plane with them
  // on the left: an empty cut only by the rule for planar references (BlockBuilder::one_sided).
  // In pile_below_cut the planar references at the plane go right, the rest lie below it: not
  // an empty cut, by the same rule from the other end.
  for (const auto& [s, traversal_cost] :
       {std::pair{random_soup(7, 5000, 0.05f), 3.0f}, std::pair{sphere_and_grid(24), 3.0f},
        std::pair{sliver_fan(13, 3000), 3.0f}, std::pair{planar_piles(17, 3000), 3.0f},
        std::pair{random_soup(19, 64, 0.5f), 3.0f}, std::pair{random_soup(23, 128, 0.5f), 3.0f},
        std::pair{random_soup(31, 256, 0.5f), 3.0f}, std::pair{random_soup(37, 150, 0.5f), 3.0f},
        std::pair{random_soup(29, 300, 0.5f), 1.0f}, std::pair{signed_zero_cells(), 0.1f},
        std::pair{separate_boxes(47, 400, 1), 3.0f}, std::pair{separate_boxes(53, 200, 6), 3.0f},
        std::pair{walled_gap(), 3.0f}, std::pair{pile_below_cut(61), 3.0f}}) {
    for (int mask_below : {-1, 256, 192, 150, 128, 100, 64, 33, 8}) {  // -1: 256 without clipping
      KdBuildOptions sweep;
      sweep.clip = false;
      sweep.mask_below = 0;
      sweep.empty_cut = 2.0f;  // every node swept: the bit masks have no such shortcut
      sweep.traversal_cost = traversal_cost;
      KdBuildOptions masks = sweep;
      masks.mask_below = mask_below;
      const KdTree a = KdTree::build(s.positions, s.triangles, sweep);
      const KdTree b = KdTree::build(s.positions, s.triangles, masks);
      ASSERT_GT(a.nodes().size(), 1u);
      ASSERT_EQ(a.nodes().size(), b.nodes().size()) << "mask below " << mask_below;
      for (std::size_t i = 0; i < a.nodes().size(); ++i) {
        ASSERT_EQ(a.nodes()[i].bits, b.nodes()[i].bits) << "node " << i << ", mask below " << mask_below;
        ASSERT_EQ(a.nodes()[i].count, b.nodes()[i].count) << "node " << i << ", mask below " << mask_below;
      }
      ASSERT_EQ(refs_of(a), refs_of(b));
      EXPECT_EQ(a.stats().sah_cost, b.stats().sah_cost);
      EXPECT_EQ(a.stats().max_depth, b.stats().max_depth);
      EXPECT_EQ(a.stats().empty_leaves, b.stats().empty_leaves);
    }
  }
  // With clipping the stage is seen to run: the slivers' straddlers keep their root bounds
  // below the default threshold, so that tree differs from the one clipped to the leaves.
  const Soup fan = sliver_fan(13, 3000);
  KdBuildOptions sweep;
  sweep.mask_below = 0;
  const KdTree a = KdTree::build(fan.positions, fan.triangles, sweep);
  const KdTree b = KdTree::build(fan.positions, fan.triangles, KdBuildOptions{});
  EXPECT_NE(a.stats().sah_cost, b.stats().sah_cost);
}

TEST(KdTree, WideEmptyGapsAreCutWithoutTheSweep) {
  // KdBuildOptions::empty_cut: a gap of at least that fraction of the cell is cut off at the
  // references' bound; a narrower one is left to the SAH sweep, which cuts between the slabs.
  const Soup s = slabs_under_gap();
  for (const float empty_cut : {0.0f, 0.05f, 0.09f, 0.1f, 0.5f, 2.0f}) {
    SCOPED_TRACE(testing::Message() << "empty_cut " << empty_cut);
    KdBuildOptions o;
    o.empty_cut = empty_cut;
    const KdTree tree = KdTree::build(s.positions, s.triangles, o);
    const KdNode root = tree.nodes()[0];
    ASSERT_FALSE(root.is_leaf());
    ASSERT_EQ(root.axis(), 0);
    ASSERT_EQ(root.split, 1.0f);
    const KdNode slabs = tree.nodes()[root.left()];
    ASSERT_FALSE(slabs.is_leaf());
    if (empty_cut <= 0.1f / 1.1f) {
      EXPECT_EQ(slabs.axis(), 1);
      EXPECT_EQ(slabs.split, 1.0f);
      EXPECT_TRUE(slabs.child_empty(1));
      EXPECT_FALSE(slabs.child_empty(0));
    } else {
      EXPECT_EQ(slabs.axis(), 0);
      EXPECT_FALSE(slabs.child_empty(0));
      EXPECT_FALSE(slabs.child_empty(1));
    }
  }
}

// The vector code this CPU can run in the build (KdBuildOptions::simd_limit): AVX2 and AVX-512
// where it has them, so an AVX-512 machine tests the AVX2 code too.
std::vector<Isa> build_vector_isas() {
  std::vector<Isa> out;
  for (Isa isa : {Isa::Avx2, Isa::Avx512}) {
    if (cpu_supports(isa)) out.push_back(isa);
  }
  return out;
}

// Builds every soup with KdBuildOptions::simd off and on, the latter once per vector ISA the CPU
// has (each with its K_T, the bit-mask stage below `mask_below` references, with clipping and
// without) and requires node for node the same tree.
// `base`: the other options (KdBuildOptions' defaults, or a view-aware SAH's eye).
void expect_vector_build_matches_scalar(const std::vector<std::pair<Soup, float>>& soups, int mask_below,
                                        const KdBuildOptions& base = {}) {
  for (const auto& [s, traversal_cost] : soups) {
    for (bool clip : {true, false}) {
      KdBuildOptions scalar = base;
      scalar.clip = clip;
      scalar.simd = false;
      scalar.mask_below = mask_below;
      scalar.traversal_cost = traversal_cost;
      const KdTree a = KdTree::build(s.positions, s.triangles, scalar);
      ASSERT_GT(a.nodes().size(), 1u);
      for (Isa isa : build_vector_isas()) {
        SCOPED_TRACE(testing::Message() << "vector code up to " << isa_name(isa) << ", clip " << clip);
        KdBuildOptions vector = scalar;
        vector.simd = true;
        vector.simd_limit = isa;
        const KdTree b = KdTree::build(s.positions, s.triangles, vector);
        ASSERT_EQ(a.nodes().size(), b.nodes().size());
        for (std::size_t i = 0; i < a.nodes().size(); ++i) {
          ASSERT_EQ(a.nodes()[i].bits, b.nodes()[i].bits) << "node " << i;
          ASSERT_EQ(a.nodes()[i].count, b.nodes()[i].count) << "node " << i;  // or split's bits
        }
        ASSERT_EQ(refs_of(a), refs_of(b));
        EXPECT_EQ(a.stats().sah_cost, b.stats().sah_cost);
      }
    }
  }
}

TEST(KdTree, BitMaskStageVectorScanBuildsTheScalarScansTree) {
  // KdBuildOptions::simd picks the bit-mask stage's plane scan: 8 planes at a time with AVX-512
  // VPOPCNTDQ where the CPU has it, else one at a time. Same costs bit for bit and the same
  // tie rule, so node for node the same tree, with clipping above the stage or without; with
  // masks of one to four words (the default threshold, then 64 and 128).
  for (int mask_below : {KdBuildOptions{}.mask_below, 64, 128}) {
    SCOPED_TRACE(testing::Message() << "mask below " << mask_below);
    ASSERT_NO_FATAL_FAILURE(expect_vector_build_matches_scalar(
        {{random_soup(7, 5000, 0.05f), 3.0f}, {sphere_and_grid(24), 3.0f}, {sliver_fan(13, 3000), 3.0f},
         {planar_piles(17, 3000), 3.0f}, {random_soup(19, 64, 0.5f), 3.0f}, {random_soup(31, 256, 0.5f), 3.0f},
         {random_soup(37, 150, 0.5f), 3.0f}, {random_soup(29, 300, 0.5f), 1.0f}, {signed_zero_cells(), 0.1f}},
        mask_below));
  }
}

TEST(KdTree, EventSweepVectorCodeBuildsTheScalarTree) {
  // KdBuildOptions::simd also picks the event sweep's vector code where the CPU has AVX-512:
  // the SAH 16 events at a time (groups of equal positions carried across the 16 by running
  // counts) instead of one group at a time, and the split of the event lists 8 at a time
  // (sides gathered, kept events compressed, straddlers collected and references counted in the
  // same pass). The same costs bit for bit, the same tie rule and the same lists, so node for
  // node the same tree: swept down to the leaves (no bit-mask stage), with clipping and
  // without; a mesh (shared vertices: groups of a few events), piles of coincident planar
  // triangles (groups of hundreds, across many 16s), signed zeros; the 70000-triangle soup
  // also sweeps the window around its binned root's best boundary (TopBuilder::refine), and so
  // do a 70000-triangle sphere (groups of +0 and -0 in its windows: the group's first position
  // is the split's) and walled_gap() (a window of 30 equal events).
  ASSERT_NO_FATAL_FAILURE(expect_vector_build_matches_scalar(
      {{random_soup(7, 5000, 0.05f), 3.0f}, {sphere_and_grid(24), 3.0f}, {sliver_fan(13, 3000), 3.0f},
       {planar_piles(17, 3000), 3.0f}, {random_soup(29, 300, 0.5f), 1.0f}, {signed_zero_cells(), 0.1f},
       {random_soup(31, 70000, 0.02f), 3.0f}, {sphere_and_grid(132), 3.0f}, {walled_gap(), 3.0f}},
      0));
}

TEST(KdTree, KeptPolygonsAndUnmovedEventsBuildTheSameTree) {
  // With clipping, each split cuts a straddler's polygon kept from its last split at one plane
  // (KdBuildOptions::keep_clipped_polygons) and leaves its unmoved events where they are in the
  // children's lists (keep_unmoved_events). Against clipping the triangle to every node's cell
  // and making every event anew: node for node the same tree, scalar and vector code, one and
  // two threads (forked children get copies of the polygons). The soups straddle a lot: long
  // slivers, a sphere on a grid, planar piles, signed zeros, and a 20000-triangle soup of long
  // triangles (binned levels above its blocks).
  const std::vector<Soup> soups = {random_soup(7, 5000, 0.05f), sphere_and_grid(24), sliver_fan(13, 3000),
                                   planar_piles(17, 3000),      signed_zero_cells(),  random_soup(43, 20000, 0.3f)};
  for (const Soup& s : soups) {
    for (const bool simd : {false, true}) {
      for (const int threads : {1, 2}) {
        SCOPED_TRACE(testing::Message() << s.triangles.size() << " triangles, simd " << simd << ", threads " << threads);
        KdBuildOptions fresh;
        fresh.simd = simd;
        fresh.threads = threads;
        fresh.binned_root_above = 4096;  // the small soups' root splits with kept polygons too
        fresh.keep_clipped_polygons = false;
        fresh.keep_unmoved_events = false;
        const KdTree a = KdTree::build(s.positions, s.triangles, fresh);
        for (const auto& [polygons, events] : {std::pair{true, false}, std::pair{false, true}, std::pair{true, true}}) {
          SCOPED_TRACE(testing::Message() << "kept polygons " << polygons << ", unmoved events " << events);
          KdBuildOptions kept = fresh;
          kept.keep_clipped_polygons = polygons;
          kept.keep_unmoved_events = events;
          expect_same_tree(a, KdTree::build(s.positions, s.triangles, kept));
        }
      }
    }
  }
}

// The root of a tree over a dense cluster around the origin (random_soup's cube of side 2) and
// something sparse at x = `side` (+-6): a plane in x between them, its denser child the
// cluster's.
void expect_root_between_clusters(const KdTree& tree, float side) {
  const KdNode root = tree.nodes()[0];
  ASSERT_FALSE(root.is_leaf());
  ASSERT_EQ(root.axis(), 0);
  // Between the clusters (x within 1.2 of 0 and of `side`).
  ASSERT_GT(std::abs(root.split), 1.0f);
  ASSERT_LT(std::abs(root.split), 5.0f);
  ASSERT_EQ(root.split > 0.0f, side > 0.0f);
  EXPECT_EQ(root.denser(), side > 0 ? 0u : 1u);  // the child on the dense cluster's side
}

TEST(KdTree, MarksTheDenserChild) {
  // KdBuildOptions::mark_denser: a dense cluster (2000 triangles in a cube of side 2) beside a
  // sparse one (3 triangles) four units away along x: the root splits between them, and its
  // denser child is the dense cluster's, on either side. Off: the same tree with every mark 0.
  for (const float side : {6.0f, -6.0f}) {
    SCOPED_TRACE(testing::Message() << "sparse cluster at x " << side);
    Soup s = random_soup(5, 2000, 0.2f);
    const Soup sparse = random_soup(6, 3, 0.2f);
    const auto base = static_cast<unsigned>(s.positions.size());
    for (const glm::vec3& p : sparse.positions) s.positions.push_back(p + glm::vec3(side, 0.0f, 0.0f));
    for (const glm::uvec3& t : sparse.triangles) s.triangles.push_back(t + glm::uvec3(base));
    const KdTree tree = KdTree::build(s.positions, s.triangles, KdBuildOptions{});
    ASSERT_NO_FATAL_FAILURE(expect_root_between_clusters(tree, side));
    KdBuildOptions off;
    off.mark_denser = false;
    const KdTree plain = KdTree::build(s.positions, s.triangles, off);
    ASSERT_EQ(plain.nodes().size(), tree.nodes().size());
    std::size_t marked = 0;
    for (std::size_t i = 0; i < tree.nodes().size(); ++i) {
      const KdNode a = tree.nodes()[i], b = plain.nodes()[i];
      if (a.is_leaf()) {
        EXPECT_EQ(a.bits, b.bits) << "node " << i;
        continue;
      }
      EXPECT_EQ(b.denser(), 0u) << "node " << i;
      EXPECT_EQ(a.bits & ~16u, b.bits) << "node " << i;  // all but the mark
      EXPECT_EQ(a.split, b.split) << "node " << i;
      marked += a.denser();
    }
    EXPECT_GT(marked, 0u);
  }
}

// The logging walk of walk_order.h for `isa` (nullptr where not compiled in).
WalkLogFn walk_log_for(Isa isa) {
  switch (isa) {
#ifdef RTC_HAVE_ISA_SSE42
    case Isa::Sse42:
      return &isa_sse42::walk_log;
#endif
#ifdef RTC_HAVE_ISA_AVX2
    case Isa::Avx2:
      return &isa_avx2::walk_log;
#endif
#ifdef RTC_HAVE_ISA_AVX512
    case Isa::Avx512:
      return &isa_avx512::walk_log;
#endif
    default:
      return nullptr;
  }
}

// The walk orders themselves, which no answer shows (occlusion is the same in every order): a
// shadow ray crossing the dense cluster of MarksTheDenserChild and a large triangle 6 units away
// enters first the root's child nearer along it (Near), the farther one (Far), or the one the
// root marks denser (Dense), except where a live lane starts in the near child: then the far one.
// Which of the wall and the cluster's triangles that lie wholly in its child is tested first says
// which child the root's step entered first (the steps below are not checked). Every ISA the CPU
// has, packets of 3 rays and single rays.
TEST(KdTraversal, ShadowWalksEnterTheChildTheirOrderNames) {
  for (const float side : {6.0f, -6.0f}) {
    SCOPED_TRACE(testing::Message() << "wall at x " << side);
    Soup s = random_soup(5, 2000, 0.2f);
    const auto wall = static_cast<std::uint32_t>(s.triangles.size());
    add_wall(s, side, 1);
    const KdTree tree = KdTree::build(s.positions, s.triangles, KdBuildOptions{});
    ASSERT_NO_FATAL_FAILURE(expect_root_between_clusters(tree, side));
    const KdNode root = tree.nodes()[0];
    const auto cluster_only = [&](std::uint32_t id) {
      if (id >= wall) return false;
      const glm::uvec3 t = s.triangles[id];
      for (int k = 0; k < 3; ++k) {
        const float x = s.positions[t[k]].x;
        if (side > 0 ? x >= root.split : x <= root.split) return false;
      }
      return true;
    };
    // Where a ray along x through the cluster's middle and the wall starts, and which side each
    // order enters first there (true: the wall's).
    struct Start {
      float org_x;
      bool toward_wall;
      bool near_wall, far_wall, dense_wall;
    };
    const float w = side > 0 ? 1.0f : -1.0f;  // towards the wall
    const Start beyond_wall{20.0f * w, false, true, false, false};     // the wall's side is near
    const Start beyond_cluster{-20.0f * w, true, false, true, false};  // the cluster's is near
    const Start inside{0.0f, true, false, true, true};  // the cluster's is near, but holds the origin
    const auto query = [&](const Start& st, int lane) {
      RayQuery q;
      q.org = glm::vec3(st.org_x, 0.01f * static_cast<float>(lane), 0.02f);
      q.dir = glm::vec3(st.toward_wall ? w : -w, 0.0f, 0.0f);
      return q;
    };
    // Packets of 3 rays (lanes past them inactive: copies of `filler` where given, else of the
    // last ray), and the side each order enters first.
    struct PacketCase {
      const char* what;
      const Start* lane[3];
      const Start* filler;
      bool near_wall, far_wall, dense_wall;
    };
    const PacketCase packets[] = {
        {"from beyond the wall", {&beyond_wall, &beyond_wall, &beyond_wall}, nullptr, true, false, false},
        {"from beyond the cluster", {&beyond_cluster, &beyond_cluster, &beyond_cluster}, nullptr, false, true, false},
        {"from inside the cluster", {&inside, &inside, &inside}, nullptr, false, true, true},
        // One lane starting in the near child sends the packet to the far one first.
        {"one lane from inside", {&beyond_cluster, &inside, &beyond_cluster}, nullptr, false, true, true},
        // An inactive lane does not.
        {"an inactive lane from inside", {&beyond_cluster, &beyond_cluster, &beyond_cluster}, &inside, false, true,
         false},
    };
    const auto first_side = [&](const WalkLog& log, bool& wall_first) {
      ASSERT_GT(log.count, 0);
      // The wall, or one of the cluster's triangles that lies wholly on its side of the root's
      // plane (those crossing it are in both children), whichever comes first.
      const std::uint32_t* end = log.ids + std::min(log.count, WalkLog::kMax);
      const std::uint32_t* first =
          std::find_if(log.ids, end, [&](std::uint32_t id) { return id == wall || cluster_only(id); });
      ASSERT_NE(first, end);
      wall_first = *first == wall;
    };
    for (const Isa isa : compiled_isas()) {
      if (!cpu_supports(isa)) continue;
      SCOPED_TRACE(testing::Message() << isa_name(isa));
      const WalkLogFn walk = walk_log_for(isa);
      ASSERT_NE(walk, nullptr);
      for (const ShadowWalk order : {ShadowWalk::Near, ShadowWalk::Far, ShadowWalk::Dense}) {
        SCOPED_TRACE(testing::Message() << "order " << static_cast<int>(order));
        const auto expected = [order](bool near_wall, bool far_wall, bool dense_wall) {
          return order == ShadowWalk::Near ? near_wall : order == ShadowWalk::Far ? far_wall : dense_wall;
        };
        for (const Start* st : {&beyond_wall, &beyond_cluster, &inside}) {
          SCOPED_TRACE(testing::Message() << "a single ray from x " << st->org_x);
          const RayQuery q = query(*st, 0);
          WalkLog log;
          walk(tree, &q, 1, nullptr, false, order, log);
          bool wall_first = false;
          ASSERT_NO_FATAL_FAILURE(first_side(log, wall_first));
          EXPECT_EQ(wall_first, expected(st->near_wall, st->far_wall, st->dense_wall));
          EXPECT_EQ(log.occluded, 1u);  // the wall blocks it
        }
        for (const PacketCase& c : packets) {
          SCOPED_TRACE(testing::Message() << "a packet " << c.what);
          RayQuery rays[3];
          for (int i = 0; i < 3; ++i) rays[i] = query(*c.lane[i], i);
          const RayQuery filler = c.filler != nullptr ? query(*c.filler, 3) : RayQuery{};
          WalkLog log;
          walk(tree, rays, 3, c.filler != nullptr ? &filler : nullptr, true, order, log);
          bool wall_first = false;
          ASSERT_NO_FATAL_FAILURE(first_side(log, wall_first));
          EXPECT_EQ(wall_first, expected(c.near_wall, c.far_wall, c.dense_wall));
          EXPECT_EQ(log.occluded, 0x7u);  // the wall blocks them all
        }
      }
    }
  }
}

TEST(KdTree, BinnedLevelsVectorBinsBuildTheScalarTree) {
  // Above KdBuildOptions::exact_below references a node is split by the binned SAH, whose bins
  // of 16 references at a time come from vector code where the CPU has AVX-512 (the boxes
  // gathered, clamped to the node and binned by the scalar loop's float operations in its
  // order). The same counts, so node for node the same tree. A low exact_below bins nodes down
  // to a few dozen references: boxes that cross the node's bounds (clamped), lie in a plane
  // (planar piles), sit on signed zeros, and chunks whose last step holds fewer than 16.
  for (int exact_below : {40, 300}) {
    SCOPED_TRACE(testing::Message() << "exact below " << exact_below);
    KdBuildOptions base;
    base.exact_below = exact_below;
    ASSERT_NO_FATAL_FAILURE(expect_vector_build_matches_scalar(
        {{random_soup(7, 5000, 0.05f), 3.0f}, {sphere_and_grid(24), 3.0f}, {sliver_fan(13, 3000), 3.0f},
         {planar_piles(17, 3000), 3.0f}, {random_soup(29, 301, 0.5f), 1.0f}, {signed_zero_cells(), 0.1f}},
        64, base));
  }
}

// A view-aware SAH (KdBuildOptions::footprint_pixels) aimed from `eye` with pixels `slope`
// wide per unit of distance.
KdBuildOptions aimed(glm::vec3 eye, float slope, float pixels = 2.0f, int max_refs = 32) {
  KdBuildOptions o;
  o.footprint_pixels = pixels;
  o.footprint_max_refs = max_refs;
  o.pixel_slope = slope;
  o.footprint_eye = eye;
  return o;
}

TEST(KdTree, ViewAwareSahVectorCodeBuildsTheScalarTree) {
  // The footprint's lengths (footprint_length) go through the same float operations in the
  // scalar SAH, the event sweep's vector code and the bit-mask stage's plane scans, so node for
  // node the same tree: swept to the leaves, with the bit masks below 64, and from a binned
  // root (70000 triangles), here for nodes of every size. The eye outside every soup, a few
  // units from most, pixels 0.01 wide per unit: lengths about 0.05-0.1 longer near the soups,
  // the size of their deeper nodes.
  const KdBuildOptions view = aimed(glm::vec3(0.3f, -0.2f, 4.0f), 0.01f, 2.0f, 1 << 30);
  {  // the footprint is on: not the plain tree
    const Soup s = random_soup(7, 5000, 0.05f);
    KdBuildOptions plain;
    plain.footprint_pixels = 0.0f;
    EXPECT_LT(KdTree::build(s.positions, s.triangles, view).stats().nodes,
              KdTree::build(s.positions, s.triangles, plain).stats().nodes);
  }
  for (int mask_below : {0, 64}) {
    SCOPED_TRACE(testing::Message() << "mask below " << mask_below);
    ASSERT_NO_FATAL_FAILURE(expect_vector_build_matches_scalar(
        {{random_soup(7, 5000, 0.05f), 3.0f}, {sphere_and_grid(24), 3.0f}, {sliver_fan(13, 3000), 3.0f},
         {planar_piles(17, 3000), 3.0f}, {random_soup(29, 300, 0.5f), 1.0f}, {signed_zero_cells(), 0.1f},
         {random_soup(31, 70000, 0.02f), 3.0f}},
        mask_below, view));
  }
}

TEST(KdTree, ViewAwareSahIsThePlainSahWhenOff) {
  // No pixel width (no camera given), no footprint or no node small enough is the plain SAH to
  // the bit; a footprint wider than the small nodes leaves fewer of them, and the plain SAH
  // cost it reports stays close to the plain tree's.
  const Soup s = random_soup(41, 20000, 0.01f);
  KdBuildOptions plain_options;
  plain_options.footprint_pixels = 0.0f;
  const KdTree plain = KdTree::build(s.positions, s.triangles, plain_options);
  const glm::vec3 eye(0.0f, 0.0f, 5.0f);
  expect_same_tree(plain, KdTree::build(s.positions, s.triangles, KdBuildOptions{}));
  expect_same_tree(plain, KdTree::build(s.positions, s.triangles, aimed(eye, 0.0f)));
  expect_same_tree(plain, KdTree::build(s.positions, s.triangles, aimed(eye, 0.01f, 0.0f)));
  expect_same_tree(plain, KdTree::build(s.positions, s.triangles, aimed(eye, 0.01f, 2.0f, 0)));
  const KdTree wide = KdTree::build(s.positions, s.triangles, aimed(eye, 0.002f));
  EXPECT_LT(wide.stats().nodes, plain.stats().nodes * 19 / 20);  // 9,521 against 10,493
  EXPECT_LT(wide.stats().sah_cost, plain.stats().sah_cost * 1.05);  // 264.4 against 262.9
  EXPECT_GE(wide.stats().sah_cost, plain.stats().sah_cost * 0.99);
}

TEST(KdTree, BinnedRootRefinesToTheExactPlaneFromEveryChunk) {
  // Two clusters of tiny triangles, 30000 in x < 0.41 and 40000 in x >= 0.70123, 70000 in all:
  // the root is binned (256 bins) and, at 65536 references or more, refined by sweeping the
  // exact event positions in the bins around its best boundary. Every plane in the gap puts
  // the same triangles on each side, and the larger cluster makes the cost fall as the plane
  // moves right, so the best is the leftmost vertex of the right cluster, 0.70123, which no
  // bin boundary hits (179.51 bins). The root's references are collected in chunks of 14001;
  // the triangle holding that vertex is put in each chunk in turn, so a chunk whose events the
  // window lost would move the plane.
  constexpr int kLeft = 30000, kCount = 70000;
  constexpr float kEdge = 0.70123f;
  for (const int holder : {5, 20000, 30001, 45000, 69999}) {
    SCOPED_TRACE("vertex at the edge in triangle " + std::to_string(holder));
    std::mt19937 rng(41);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f), off(0.0f, 0.002f);
    Soup s;
    for (int i = 0; i < kCount; ++i) {
      const float x = i == holder ? kEdge : i < kLeft ? 0.4f * unit(rng) : 0.7013f + 0.29f * unit(rng);
      const glm::vec3 c(x, unit(rng), unit(rng));
      s.positions.push_back(c);
      s.positions.push_back(c + glm::vec3(off(rng), off(rng), 0.0f));
      s.positions.push_back(c + glm::vec3(off(rng), 0.0f, off(rng)));
      const auto b = static_cast<unsigned>(3 * i);
      s.triangles.emplace_back(b, b + 1, b + 2);
    }
    const KdTree tree = KdTree::build(s.positions, s.triangles);
    ASSERT_FALSE(tree.nodes()[0].is_leaf());
    EXPECT_EQ(tree.nodes()[0].axis(), 0u);
    EXPECT_EQ(tree.nodes()[0].split, kEdge);
  }
}

KdBuildOptions with_test(bool watertight) {
  KdBuildOptions o;
  o.watertight = watertight;
  return o;
}

const char* test_name(bool watertight) { return watertight ? "watertight" : "wald"; }

// The build's records eight at a time (make_tri_accels with AVX-512) are make_tri_accel's, every
// byte: random triangles at scales from 2^-100 to 2^100, slivers, each dominant axis, small ones
// far from the origin, triangles with zero area (collinear, repeated vertices) and with infinite
// or NaN coordinates, in runs that are not multiples of eight. Fails when a lane picks another k,
// u or v, or keeps a record the scalar code drops (both tried). The double operations' order is
// the scalar code's by construction: a reordering changes a float field only in rare roundings,
// which these inputs did not meet. Without AVX-512 both calls take the scalar code, and the test
// reports itself skipped.
TEST(KdTree, RecordsEightAtATimeAreTheScalarOnes) {
  std::mt19937 rng(42);
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
  std::uniform_int_distribution<int> exponent(-100, 100);
  std::vector<glm::vec3> positions;
  const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
  const auto add = [&](glm::vec3 a, glm::vec3 b, glm::vec3 c) {
    positions.push_back(a);
    positions.push_back(b);
    positions.push_back(c);
  };
  for (int i = 0; i < 3000; ++i) {
    if (i == 1500) {  // the special cases among the others
      add({0, 0, 0}, {1, 1, 1}, {2, 2, 2});  // collinear
      add({1, 2, 3}, {1, 2, 3}, {4, 5, 6});  // a repeated vertex
      add({0, 0, 0}, {inf, 0, 0}, {0, 1, 0});
      add({0, 0, 0}, {1, 0, 0}, {0, nan, 0});
      add({-inf, 0, 0}, {1, 0, 0}, {0, 1, 0});
      add({0, 0, 0}, {3e38f, 0, 0}, {0, 3e38f, 0});  // a normal beyond float, finite in double
    }
    const float scale = std::ldexp(1.0f, exponent(rng));
    const glm::vec3 a(unit(rng), unit(rng), unit(rng));
    glm::vec3 b(unit(rng), unit(rng), unit(rng)), c(unit(rng), unit(rng), unit(rng));
    switch (i % 6) {
      case 1:  // a sliver
        c = a + (b - a) * 0.5f + glm::vec3(unit(rng), unit(rng), unit(rng)) * 1e-6f;
        break;
      case 2:  // flat in one axis: each k in turn
        b[(i / 6) % 3] = a[(i / 6) % 3];
        c[(i / 6) % 3] = a[(i / 6) % 3];
        break;
      case 3: {  // small, far from the origin: the plane offset's products cancel
        const glm::vec3 far = glm::vec3(unit(rng), unit(rng), unit(rng)) * 1e7f;
        add(far + a, far + b, far + c);
        continue;
      }
      default:
        break;
    }
    add(a * scale, b * scale, c * scale);
  }
  std::vector<glm::uvec3> triangles;
  for (unsigned t = 0; 3 * t + 2 < positions.size(); ++t) triangles.emplace_back(3 * t, 3 * t + 1, 3 * t + 2);
  std::size_t degenerate = 0;
  for (const std::size_t first : {std::size_t{0}, std::size_t{5}}) {
    for (const Isa isa : {Isa::Avx512, Isa::Sse42}) {
      const std::size_t count = triangles.size() - first - 3;  // not a multiple of 8
      std::vector<TriRecord> out(count);
      make_tri_accels(positions, triangles, first, count, out.data(), isa);
      for (std::size_t i = 0; i < count; ++i) {
        const glm::uvec3 t = triangles[first + i];
        const TriAccel expected = make_tri_accel(positions[t.x], positions[t.y], positions[t.z]);
        if (isa == Isa::Avx512 && first == 0 && expected.k == 3) ++degenerate;
        ASSERT_EQ(std::memcmp(&out[i].wald, &expected, sizeof(TriAccel)), 0) << "triangle " << first + i;
      }
    }
  }
  EXPECT_GE(degenerate, 4u);  // the collinear, repeated-vertex and non-finite ones at least
  if (!cpu_supports(Isa::Avx512)) GTEST_SKIP() << "no AVX-512 here: only the scalar code was compared";
}

TEST(KdTree, DegenerateTrianglesAreSkipped) {
  Soup s;
  s.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {2, 0, 0}};
  s.triangles = {{0, 1, 2}, {0, 1, 3}, {0, 0, 2}};  // the last two have zero area
  for (bool watertight : {false, true}) {
    SCOPED_TRACE(test_name(watertight));
    const KdTree tree = KdTree::build(s.positions, s.triangles, with_test(watertight));
    EXPECT_EQ(tree.watertight(), watertight);
    EXPECT_EQ(tree.stats().degenerate, 2u);
    // Only triangle 0 is referenced, with its record (k = 2 for Wald's, 0 for the vertices).
    ASSERT_EQ(tree.leaf_records().size(), 1u);
    EXPECT_EQ(refs_of(tree), std::vector<std::uint32_t>{0});
    EXPECT_EQ(tree.leaf_records()[0].wald.k, watertight ? 0u : 2u);
    EXPECT_EQ(tree.leaf_records()[0].wald.id, 0u);
    EXPECT_EQ(make_tri_accel(s.positions[0], s.positions[1], s.positions[3]).k, 3u);
    EXPECT_EQ(make_tri_verts(s.positions[0], s.positions[0], s.positions[2]).k, 3u);
    // A ray through all three (the degenerate ones lie on the x axis and the y axis).
    RayQuery q;
    q.org = {0.5f, 0.0f, 1.0f};
    q.dir = {0.0f, 0.0f, -1.0f};
    RayHit h;
    trace_kernels().intersect(tree, &q, &h, 1, false);
    EXPECT_EQ(h.prim, 0u);
  }
}

// The records are made in chunks of 1,024 triangles, each with its own box and count of
// triangles kept, merged in order: with degenerate triangles scattered over many chunks (and a
// whole chunk of them) the tree references every other triangle and no degenerate one, its
// bounds hold exactly the kept triangles, and it is the tree of the kept triangles alone.
TEST(KdTree, DegenerateTrianglesAcrossRecordChunksAreSkipped) {
  Soup s = random_soup(41, 6000, 0.05f);
  // The scene's extremes in the first and the last chunk, and a degenerate triangle beyond them.
  s.positions[3 * 1] = {-3.0f, -3.0f, -3.0f};
  s.positions[3 * 5999 + 2] = {3.0f, 3.0f, 3.0f};
  s.positions[3 * 10] = {9.0f, 9.0f, 9.0f};  // triangle 10 is degenerate below (10 % 7 == 3)
  std::vector<bool> degenerate(s.triangles.size(), false);
  for (std::size_t i = 0; i < s.triangles.size(); ++i) {
    if (i % 7 == 3 || (i >= 2048 && i < 3072)) {  // chunk 2 wholly
      s.triangles[i].z = s.triangles[i].x;
      degenerate[i] = true;
    }
  }
  Soup kept;
  kept.positions = s.positions;
  std::vector<std::uint32_t> kept_ids;
  Aabb expected_box;
  for (std::size_t i = 0; i < s.triangles.size(); ++i) {
    if (degenerate[i]) continue;
    kept.triangles.push_back(s.triangles[i]);
    kept_ids.push_back(static_cast<std::uint32_t>(i));
    for (int v = 0; v < 3; ++v) expected_box.extend(s.positions[s.triangles[i][v]]);
  }
  for (const int threads : {1, 2}) {
    SCOPED_TRACE(testing::Message() << threads << " threads");
    KdBuildOptions options;
    options.threads = threads;
    const KdTree tree = KdTree::build(s.positions, s.triangles, options);
    EXPECT_EQ(tree.stats().degenerate, s.triangles.size() - kept.triangles.size());
    std::vector<bool> seen(s.triangles.size(), false);
    for (const std::uint32_t r : tree.prim_refs()) {
      if (r == kLeafBoxRef) continue;
      ASSERT_LT(r, s.triangles.size());
      EXPECT_FALSE(degenerate[r]) << "triangle " << r;
      seen[r] = true;
    }
    for (std::size_t i = 0; i < s.triangles.size(); ++i) EXPECT_EQ(seen[i], !degenerate[i]) << "triangle " << i;
    EXPECT_EQ(expected_box.lo, glm::vec3(-3.0f));
    EXPECT_EQ(expected_box.hi, glm::vec3(3.0f));
    EXPECT_TRUE(glm::all(glm::lessThanEqual(tree.bounds().lo, expected_box.lo)));
    EXPECT_TRUE(glm::all(glm::greaterThanEqual(tree.bounds().hi, expected_box.hi)));
    EXPECT_TRUE(glm::all(glm::lessThan(tree.bounds().hi, glm::vec3(3.01f))));  // not the degenerate one
    // The same tree as one over the kept triangles only, given their ids.
    const KdTree alone = KdTree::build(kept.positions, kept.triangles, options, kept_ids);
    ASSERT_EQ(tree.nodes().size(), alone.nodes().size());
    for (std::size_t i = 0; i < tree.nodes().size(); ++i) {
      ASSERT_EQ(tree.nodes()[i].bits, alone.nodes()[i].bits) << "node " << i;
      ASSERT_EQ(tree.nodes()[i].count, alone.nodes()[i].count) << "node " << i;
    }
    EXPECT_EQ(tree.bounds().lo, alone.bounds().lo);
    EXPECT_EQ(tree.bounds().hi, alone.bounds().hi);
    EXPECT_EQ(tree.stats().sah_cost, alone.stats().sah_cost);
    ASSERT_EQ(tree.leaf_records().size(), alone.leaf_records().size());
    for (std::size_t i = 0; i < tree.leaf_records().size(); ++i) {
      ASSERT_EQ(std::memcmp(&tree.leaf_records()[i], &alone.leaf_records()[i], sizeof(TriRecord)), 0) << i;
    }
  }
}

TEST(KdTree, WatertightRecordsHoldTheVerticesAndTheSameTree) {
  const Soup s = sphere_and_grid(16);
  const KdTree wald = KdTree::build(s.positions, s.triangles);
  const KdTree woop = KdTree::build(s.positions, s.triangles, with_test(true));
  EXPECT_FALSE(wald.watertight());
  EXPECT_TRUE(woop.watertight());
  ASSERT_EQ(wald.nodes().size(), woop.nodes().size());
  ASSERT_EQ(refs_of(wald), refs_of(woop));
  ASSERT_EQ(woop.leaf_records().size(), woop.prim_refs().size());
  for (std::size_t i = 0; i < woop.prim_refs().size(); ++i) {
    ASSERT_EQ(wald.leaf_records()[i].wald.id, woop.leaf_records()[i].wald.id);
    const std::uint32_t id = woop.prim_refs()[i];
    if (id == kLeafBoxRef) {  // the same LeafBox in both
      ASSERT_EQ(std::memcmp(&wald.leaf_records()[i], &woop.leaf_records()[i], sizeof(TriRecord)), 0);
      continue;
    }
    const TriVerts& v = woop.leaf_records()[i].watertight;
    ASSERT_EQ(v.id, id);
    ASSERT_EQ(v.k, 0u);
    const glm::uvec3 t = s.triangles[id];
    EXPECT_EQ(glm::vec3(v.ax, v.ay, v.az), s.positions[t.x]);
    EXPECT_EQ(glm::vec3(v.bx, v.by, v.bz), s.positions[t.y]);
    EXPECT_EQ(glm::vec3(v.cx, v.cy, v.cz), s.positions[t.z]);
  }
}

TEST(KdTree, EmptyInputGivesATreeEveryRayMisses) {
  const std::vector<glm::vec3> p;
  const std::vector<glm::uvec3> t;
  const KdTree tree = KdTree::build(p, t);
  EXPECT_TRUE(tree.empty());
  RayQuery q;
  RayHit h;
  trace_kernels().intersect(tree, &q, &h, 1, true);
  EXPECT_EQ(h.prim, kNoHit);
}

TEST(TriAccel, IsFortyEightBytesAndGivesBarycentrics) {
  static_assert(sizeof(TriAccel) == 48 && sizeof(TriVerts) == 48 && sizeof(TriRecord) == 48);
  std::vector<glm::vec3> p = {{0, 0, 0}, {2, 0, 0}, {0, 2, 0}};
  std::vector<glm::uvec3> t = {{0, 1, 2}};
  for (bool watertight : {false, true}) {
    SCOPED_TRACE(test_name(watertight));
    const KdTree tree = KdTree::build(p, t, with_test(watertight));
    // Both windings, and a direction whose largest component is negative (Woop swaps kx, ky).
    for (const glm::vec3 dir : {glm::vec3(0.0f, 0.0f, -1.0f), glm::vec3(0.0f, 0.0f, 1.0f)}) {
      RayQuery q;
      q.org = {0.5f, 0.25f, -3.0f * dir.z};
      q.dir = dir;
      RayHit h;
      trace_kernels().intersect(tree, &q, &h, 1, false);
      ASSERT_EQ(h.prim, 0u);
      EXPECT_FLOAT_EQ(h.t, 3.0f);
      EXPECT_FLOAT_EQ(h.beta, 0.25f);   // weight of vertex 1 = x / 2
      EXPECT_FLOAT_EQ(h.gamma, 0.125f); // weight of vertex 2 = y / 2
    }
  }
}

std::vector<RayQuery> random_rays(std::uint32_t seed, std::size_t count, bool coherent) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<RayQuery> rays(count);
  const glm::vec3 eye(0.3f, 0.2f, 4.0f);
  for (std::size_t i = 0; i < count; ++i) {
    RayQuery& r = rays[i];
    if (coherent) {
      r.org = eye;
      r.dir = glm::normalize(glm::vec3(u(rng) * 0.6f, u(rng) * 0.6f, -1.0f));
    } else {
      r.org = glm::vec3(u(rng), u(rng), u(rng)) * 3.0f;
      r.dir = glm::vec3(u(rng), u(rng), u(rng));
    }
  }
  return rays;
}

// Brute force in double: the nearest triangle each ray hits (NaN-safe, t > 0).
std::vector<RayHit> brute_force(const Soup& s, const std::vector<RayQuery>& rays) {
  std::vector<RayHit> out(rays.size());
  for (std::size_t i = 0; i < rays.size(); ++i) {
    double best = std::numeric_limits<double>::infinity();
    for (std::uint32_t t = 0; t < s.triangles.size(); ++t) {
      double b = 0;
      const glm::uvec3 tri = s.triangles[t];
      const double x = test::ray_triangle_t(rays[i], s.positions[tri.x], s.positions[tri.y], s.positions[tri.z], &b);
      if (b >= 0.0 && x > 0.0 && x < best) {
        best = x;
        out[i] = RayHit{static_cast<float>(x), 0, 0, t};
      }
    }
    if (out[i].prim == kNoHit) out[i].t = rays[i].t_max;
  }
  return out;
}

// The walks do test the boxes: with every box moved away from its triangles, rays that hit
// triangles of boxed leaves miss them, in packets and alone; put back, the hits return.
TEST(KdTraversal, LeafBoxesAreTestedBeforeTheTriangles) {
  const Soup s = sphere_and_grid(24);
  KdBuildOptions o;
  o.leaf_box_saving = 1e-6f;
  KdTree tree = KdTree::build(s.positions, s.triangles, o);
  ASSERT_GT(tree.stats().leaf_boxes, 0u);
  const std::vector<RayQuery> rays = random_rays(29, 20000, true);
  TriRecord* records = const_cast<TriRecord*>(tree.leaf_records().data());
  for (const bool packets : {true, false}) {
    std::vector<RayHit> before(rays.size()), moved(rays.size()), after(rays.size());
    trace_kernels().intersect(tree, rays.data(), before.data(), rays.size(), packets);
    std::vector<TriRecord> saved(tree.leaf_records().begin(), tree.leaf_records().end());
    for (std::size_t i = 0; i < tree.prim_refs().size(); ++i) {
      if (tree.prim_refs()[i] != kLeafBoxRef) continue;
      LeafBox& b = records[i].box;
      b.lo_x = b.hi_x = 1e6f;  // a flat box far off the scene
    }
    trace_kernels().intersect(tree, rays.data(), moved.data(), rays.size(), packets);
    std::copy(saved.begin(), saved.end(), records);
    trace_kernels().intersect(tree, rays.data(), after.data(), rays.size(), packets);
    std::size_t hits = 0, lost = 0;
    for (std::size_t i = 0; i < rays.size(); ++i) {
      hits += before[i].prim != kNoHit;
      lost += before[i].prim != kNoHit && moved[i].prim != before[i].prim;
      ASSERT_EQ(after[i].prim, before[i].prim) << "ray " << i;
    }
    EXPECT_GT(hits, rays.size() / 4);
    EXPECT_GT(lost, hits / 20) << (packets ? "packets" : "single rays") << ": the boxes hid nothing";
  }
}

TEST(KdTraversal, AgreesWithBruteForceDouble) {
  for (bool coherent : {true, false}) {
    for (bool watertight : {false, true}) {
    for (const Soup& s : {random_soup(5, 2000, 0.1f), sphere_and_grid(20)}) {
      const std::uint32_t seed = coherent ? 17u : 19u;
      SCOPED_TRACE("random_rays seed " + std::to_string(seed) + ", " + test_name(watertight));
      const std::vector<RayQuery> rays = random_rays(seed, 20000, coherent);
      const KdTree tree = KdTree::build(s.positions, s.triangles, with_test(watertight));
      std::vector<RayHit> hits(rays.size());
      trace_kernels().intersect(tree, rays.data(), hits.data(), rays.size(), true);
      const std::vector<RayHit> ref = brute_force(s, rays);
      // Origins inside the scene make t small next to the coordinates, so float's error in t
      // is absolute (a few ulps of the scene extent, here 3), not relative.
      const test::HitComparison c =
          test::compare_hits(s.positions, s.triangles, rays, hits, ref, 1e-5, 1e-3, 3e-6);
      SCOPED_TRACE(c.summary());
      std::printf("AgreesWithBruteForceDouble: %s rays, %s, %zu triangles: %s\n", coherent ? "coherent" : "incoherent",
                  test_name(watertight), s.triangles.size(), c.summary().c_str());
      for (std::size_t i : c.examples) ADD_FAILURE() << test::describe_ray(rays[i]);
      // A ray grazing a shared edge may slip past in float (Wald's test is not watertight);
      // such misses are rare and must all be edge cases: no triangle interior is ever missed.
      EXPECT_EQ(c.hit_miss_disagree - c.hit_miss_on_edge, 0u);
      EXPECT_LE(c.hit_miss_disagree, rays.size() / 10000);
      // Likewise a nearer triangle's silhouette edge clipped by one side and slipped past by the
      // other: allowed, as rare as the cracks (none in any of these eight runs when written).
      EXPECT_LE(c.edge_grazes, rays.size() / 10000);
      EXPECT_EQ(c.same_prim_t_bad, 0u);
      EXPECT_EQ(c.bad_ties, 0u);
    }
    }
  }
}

TEST(KdTraversal, PacketsAndSingleRaysGiveTheSameBits) {
  const Soup s = sphere_and_grid(32);
  for (bool watertight : {false, true}) {
  const KdTree tree = KdTree::build(s.positions, s.triangles, with_test(watertight));
  for (bool coherent : {true, false}) {
    SCOPED_TRACE("random_rays seed 23, coherent " + std::to_string(coherent) + ", " + test_name(watertight));
    const std::vector<RayQuery> rays = random_rays(23, 40000, coherent);
    std::vector<RayHit> a(rays.size()), b(rays.size());
    std::vector<std::uint8_t> oa(rays.size()), ob(rays.size());
    trace_kernels().intersect(tree, rays.data(), a.data(), rays.size(), true);
    trace_kernels().intersect(tree, rays.data(), b.data(), rays.size(), false);
    trace_kernels().occluded(tree, rays.data(), oa.data(), rays.size(), true);
    trace_kernels().occluded(tree, rays.data(), ob.data(), rays.size(), false);
    for (std::size_t i = 0; i < rays.size(); ++i) {
      ASSERT_EQ(std::memcmp(&a[i], &b[i], sizeof(RayHit)), 0) << test::describe_ray(rays[i]);
      ASSERT_EQ(oa[i], ob[i]) << test::describe_ray(rays[i]);
      ASSERT_EQ(oa[i] != 0, a[i].prim != kNoHit) << test::describe_ray(rays[i]);
    }
  }
  }
}

TEST(KdTraversal, EveryIsaGivesTheSameBits) {
  const Soup s = sphere_and_grid(32);
  int tried = 0;
  for (bool watertight : {false, true}) {
  const KdTree tree = KdTree::build(s.positions, s.triangles, with_test(watertight));
  for (bool coherent : {true, false}) {
    const std::vector<RayQuery> rays = random_rays(29, 40000, coherent);
    std::vector<RayHit> ref(rays.size()), got(rays.size());
    std::vector<std::uint8_t> oref(rays.size()), ogot(rays.size());
    trace_kernels(Isa::Sse42).intersect(tree, rays.data(), ref.data(), rays.size(), false);
    trace_kernels(Isa::Sse42).occluded(tree, rays.data(), oref.data(), rays.size(), false);
    for (const Isa isa : compiled_isas()) {
      if (!cpu_supports(isa)) {
        std::printf("EveryIsaGivesTheSameBits: this CPU lacks %s, not tried\n", std::string(isa_name(isa)).c_str());
        continue;
      }
      ++tried;
      SCOPED_TRACE(std::string(isa_name(isa)) + ", coherent " + std::to_string(coherent) + ", " +
                   test_name(watertight));
      for (bool packets : {true, false}) {
        trace_kernels(isa).intersect(tree, rays.data(), got.data(), rays.size(), packets);
        trace_kernels(isa).occluded(tree, rays.data(), ogot.data(), rays.size(), packets);
        for (std::size_t i = 0; i < rays.size(); ++i) {
          ASSERT_EQ(std::memcmp(&ref[i], &got[i], sizeof(RayHit)), 0) << "packets " << packets << " "
                                                                      << test::describe_ray(rays[i]);
          ASSERT_EQ(oref[i], ogot[i]) << "packets " << packets << " " << test::describe_ray(rays[i]);
        }
      }
    }
  }
  }
  EXPECT_GE(tried, 4);  // SSE4.2 at least, twice per test
}

// A leaf's second word read as a float (what the single-ray walk's look-ahead computes with
// before it knows the node is a leaf) is never a denormal, boxed or not, and the count and box
// bit read back as given.
TEST(KdNode, LeafCountReadsAsANormalFloat) {
  for (const std::uint32_t count : {0u, 1u, 24u, 4095u, (1u << 23) + 5u, (1u << 30) - 1u}) {
    for (const bool boxed : {false, true}) {
      const KdNode leaf = KdNode::leaf(12345, count, boxed);
      EXPECT_TRUE(leaf.is_leaf());
      EXPECT_EQ(leaf.tri_count(), count);
      EXPECT_EQ(leaf.has_box(), boxed);
      EXPECT_EQ(leaf.is_empty_leaf(), count == 0);
      EXPECT_EQ(leaf.prim_offset(), 12345u);
      // Normal, of magnitude at least 2, below 2^30 - 2^23 references (the exponent field is
      // then 0x80-0xFE); not finite from there on.
      const float word = std::bit_cast<float>(leaf.count);
      EXPECT_NE(std::fpclassify(word), FP_SUBNORMAL) << "count " << count << ", boxed " << boxed;
      if (count < (1u << 30) - (1u << 23)) {
        EXPECT_EQ(std::fpclassify(word), FP_NORMAL) << "count " << count << ", boxed " << boxed;
        EXPECT_GE(std::fabs(word), 2.0f) << "count " << count << ", boxed " << boxed;
      } else {
        EXPECT_FALSE(std::isfinite(word)) << "count " << count << ", boxed " << boxed;
      }
    }
  }
  EXPECT_TRUE(KdNode{}.is_empty_leaf());  // the default node: an empty leaf, its word 0.0f
}

// No walk computes with a denormal operand: on some CPUs (AMD's Zen 5) each such operation takes
// a microcode assist, and the single-ray walk's look-ahead, which read a leaf's triangle count
// as a float (a denormal) at every step to a leaf, ran 2.6-3x slower there. The CPU's sticky
// denormal-operand flag (MXCSR.DE, bit 1; flush-to-zero and denormals-are-zero cleared, so that
// it is raised) is cleared before each ISA's walks on this thread and read after them.
TEST(KdTraversal, WalksComputeWithNoDenormalOperand) {
  constexpr unsigned kDenormalFlag = 1u << 1, kDaz = 1u << 6, kFtz = 1u << 15;
  const unsigned saved = _mm_getcsr();
  // Whether `walk` raises the flag: cleared (and the flushing modes off) before, read after.
  const auto raises_denormal = [saved](auto&& walk) {
    _mm_setcsr(saved & ~(kDenormalFlag | kDaz | kFtz));
    walk();
    const unsigned after = _mm_getcsr();
    _mm_setcsr(saved);
    return (after & kDenormalFlag) != 0;
  };
  const Soup s = sphere_and_grid(32);
  int tried = 0;
  for (bool watertight : {false, true}) {
    const KdTree tree = KdTree::build(s.positions, s.triangles, with_test(watertight));
    ASSERT_GT(tree.stats().leaves - tree.stats().empty_leaves, 100u);
    for (bool coherent : {true, false}) {
      const std::vector<RayQuery> rays = random_rays(31, 4000, coherent);
      std::vector<RayHit> hits(rays.size());
      std::vector<std::uint8_t> occ(rays.size());
      for (const Isa isa : compiled_isas()) {
        if (!cpu_supports(isa)) continue;
        for (bool packets : {false, true}) {
          SCOPED_TRACE(std::string(isa_name(isa)) + ", coherent " + std::to_string(coherent) + ", packets " +
                       std::to_string(packets) + ", " + test_name(watertight));
          ++tried;
          EXPECT_FALSE(raises_denormal(
              [&] { trace_kernels(isa).intersect(tree, rays.data(), hits.data(), rays.size(), packets); }))
              << "closest hits";
          EXPECT_FALSE(raises_denormal(
              [&] { trace_kernels(isa).occluded(tree, rays.data(), occ.data(), rays.size(), packets); }))
              << "occlusion";
          EXPECT_GT(std::count_if(hits.begin(), hits.end(), [](const RayHit& h) { return h.prim != kNoHit; }), 100);
        }
      }
    }
  }
  EXPECT_GE(tried, 8);  // SSE4.2 at least
}

// Occlusion visits the leaves along each ray from its origin (Near) or from the far end of its
// segment (Far); Auto picks per run of packets from a shared tally of their times. The answer
// must be the same in every order, on every ISA, for packets and single rays: shadow rays from
// the surface points the sphere-and-grid's camera rays hit to four points of light (one inside
// the sphere, so every ray towards it is blocked), and the random rays of the other tests.
TEST(KdTraversal, EveryShadowOrderGivesTheSameAnswers) {
  const Soup s = sphere_and_grid(32);
  const glm::vec3 lights[] = {{2.0f, 3.0f, 4.0f}, {-3.0f, 0.5f, 1.0f}, {0.1f, -4.0f, -2.0f}, {0.0f, 0.0f, 0.0f}};
  int tried = 0;
  for (bool watertight : {false, true}) {
    const KdTree tree = KdTree::build(s.positions, s.triangles, with_test(watertight));
    const std::vector<RayQuery> camera = random_rays(41, 8000, true);
    std::vector<RayHit> hits(camera.size());
    trace_kernels(Isa::Sse42).intersect(tree, camera.data(), hits.data(), camera.size(), false);
    std::vector<RayQuery> rays = random_rays(43, 8000, false);
    std::size_t from_hits = 0;
    for (const glm::vec3& light : lights) {
      for (std::size_t i = 0; i < camera.size(); ++i) {
        if (hits[i].prim == kNoHit) continue;
        const glm::vec3 p = camera[i].org + hits[i].t * camera[i].dir;
        rays.push_back(RayQuery{p, 1e-4f, light - p, 1.0f});
        ++from_hits;
      }
    }
    ASSERT_GT(from_hits, camera.size());  // over a quarter of the camera rays hit
    std::vector<std::uint8_t> ref(rays.size());
    trace_kernels(Isa::Sse42).occluded_in_order(tree, rays.data(), ref.data(), rays.size(), false, ShadowOrder::Near,
                                                nullptr);
    std::size_t blocked = 0;
    for (const std::uint8_t o : ref) blocked += o;
    EXPECT_GT(blocked, rays.size() / 4);
    EXPECT_LT(blocked, rays.size() * 3 / 4);
    for (const Isa isa : compiled_isas()) {
      if (!cpu_supports(isa)) continue;
      ++tried;
      for (bool packets : {true, false}) {
        for (const ShadowOrder order : {ShadowOrder::Near, ShadowOrder::Far, ShadowOrder::Dense, ShadowOrder::Auto}) {
          SCOPED_TRACE(std::string(isa_name(isa)) + ", packets " + std::to_string(packets) + ", order " +
                       shadow_order_name(order) + ", " + test_name(watertight));
          // Auto: calls of 256 rays, as a renderer's runs, sharing one tally, so that runs in
          // both its orders are traced.
          ShadowOrderTally tally;
          std::vector<std::uint8_t> got(rays.size(), 2);
          for (std::size_t first = 0; first < rays.size(); first += 256) {
            const std::size_t n = std::min<std::size_t>(256, rays.size() - first);
            trace_kernels(isa).occluded_in_order(tree, rays.data() + first, got.data() + first, n, packets, order,
                                                 &tally);
          }
          for (std::size_t i = 0; i < rays.size(); ++i) {
            ASSERT_EQ(ref[i], got[i]) << test::describe_ray(rays[i]);
          }
          for (int w = 0; w < kShadowWalks; ++w) {
            if (order == ShadowOrder::Auto && static_cast<ShadowWalk>(w) != ShadowWalk::Near) {
              EXPECT_GT(tally.rays[w].load(), 0u) << "walk " << w;  // Auto's candidates, dense and far
            } else {
              EXPECT_EQ(tally.rays[w].load(), 0u) << "walk " << w;
            }
          }
        }
      }
    }
  }
  EXPECT_GE(tried, 2);
}

// The stream kernels load a packet's rays with vector loads and shuffles: streams whose length
// is not a multiple of the packet width (the last packet repeats its last ray in masked lanes)
// and that start anywhere in memory must give each ray the bits it gets alone.
TEST(KdTraversal, StreamsOfAnyLengthAndOffsetGiveTheSameBits) {
  const Soup s = sphere_and_grid(16);
  const KdTree tree = KdTree::build(s.positions, s.triangles, with_test(false));
  const std::vector<RayQuery> rays = random_rays(31, 200, true);
  int tried = 0;
  for (const Isa isa : compiled_isas()) {
    if (!cpu_supports(isa)) continue;
    ++tried;
    for (const std::size_t offset : {0u, 1u, 3u}) {
      for (const std::size_t count : {1u, 2u, 3u, 5u, 7u, 8u, 9u, 13u, 15u, 16u, 17u, 31u, 33u, 47u}) {
        SCOPED_TRACE(std::string(isa_name(isa)) + ", offset " + std::to_string(offset) + ", count " +
                     std::to_string(count));
        const RayQuery* first = rays.data() + offset;
        std::vector<RayHit> got(count);
        std::vector<std::uint8_t> occ(count);
        trace_kernels(isa).intersect(tree, first, got.data(), count, true);
        trace_kernels(isa).occluded(tree, first, occ.data(), count, true);
        int hits = 0;
        for (std::size_t i = 0; i < count; ++i) {
          RayHit alone;
          std::uint8_t occ_alone = 2;
          trace_kernels(Isa::Sse42).intersect(tree, first + i, &alone, 1, false);
          trace_kernels(Isa::Sse42).occluded(tree, first + i, &occ_alone, 1, false);
          ASSERT_EQ(std::memcmp(&alone, &got[i], sizeof(RayHit)), 0) << test::describe_ray(first[i]);
          ASSERT_EQ(occ_alone, occ[i]) << test::describe_ray(first[i]);
          hits += alone.prim != kNoHit ? 1 : 0;
        }
        if (count >= 16) {
          EXPECT_GT(hits, 0);  // the rays aim at the scene: most hit
        }
      }
    }
  }
  EXPECT_GE(tried, 1);
}

TEST(KdTraversal, HitsDoNotDependOnTheTreesBuildParameters) {
  // Different cost models put planes in different places (a hit exactly on a plane continues
  // into the next leaf, so ties there are settled by triangle id, not by the tree).
  const Soup s = sphere_and_grid(32);
  const std::vector<RayQuery> rays = random_rays(31, 40000, true);
  std::vector<RayHit> ref(rays.size()), got(rays.size());
  for (bool watertight : {false, true}) {
  const KdTree base = KdTree::build(s.positions, s.triangles, with_test(watertight));
  trace_kernels().intersect(base, rays.data(), ref.data(), rays.size(), true);
  for (auto [kt, ki, leaf, clip, mask, empty_cut] :
       {std::tuple{1.0f, 1.5f, 1, true, 64, 2.0f}, std::tuple{4.0f, 1.0f, 1, true, 64, 0.0f},
        std::tuple{1.0f, 3.0f, 8, true, 64, 0.5f}, std::tuple{2.0f, 1.5f, 1, false, 64, 0.1f},
        std::tuple{3.0f, 1.5f, 1, true, 0, 0.0f}, std::tuple{2.0f, 1.5f, 1, true, 9, 2.0f},
        std::tuple{1.0f, 1.5f, 1, true, 256, 0.2f}, std::tuple{2.0f, 1.0f, 1, true, 100, 0.0f},
        std::tuple{3.0f, 1.0f, 1, true, -1, 0.2f}}) {
    KdBuildOptions o = with_test(watertight);
    if (mask < 0) {  // the defaults with a view-aware SAH: lengths 0.04-0.08 longer
      mask = 64;
      o.footprint_pixels = 2.0f;
      o.pixel_slope = 0.01f;
      o.footprint_eye = glm::vec3(0.2f, 0.1f, 3.0f);
    }
    o.traversal_cost = kt;
    o.intersection_cost = ki;
    o.leaf_size = leaf;
    o.clip = clip;
    o.mask_below = mask;
    o.empty_cut = empty_cut;
    const KdTree other = KdTree::build(s.positions, s.triangles, o);
    trace_kernels().intersect(other, rays.data(), got.data(), rays.size(), true);
    for (std::size_t i = 0; i < rays.size(); ++i) {
      ASSERT_EQ(std::memcmp(&ref[i], &got[i], sizeof(RayHit)), 0)
          << test_name(watertight) << " K_T " << kt << " K_I " << ki << " leaf " << leaf << " clip " << clip
          << " mask below " << mask << " empty cut " << empty_cut << " footprint " << o.footprint_pixels << ": "
          << test::describe_ray(rays[i]);
    }
  }
  }
}

TEST(KdTraversal, ViewAwareSahAtExtremeScalesAndFootprints) {
  // The same soup 1e30 and 1e-30 across with its eye scaled alike builds the same-shaped tree
  // as at scale 1 (the distances are taken in the SAH's scaled lengths, in double), which the
  // view-aware SAH changed; an eye at 1e35 (every pixel overflows), an eye inside the soup and a
  // footprint of 1e30 pixels build trees whose hits are the plain tree's, bit for bit.
  const Soup s = random_soup(43, 3000, 0.02f);
  const glm::vec3 eye(0.1f, 0.2f, 4.0f);
  KdBuildOptions plain_options;
  plain_options.footprint_pixels = 0.0f;
  const KdTree plain = KdTree::build(s.positions, s.triangles, plain_options);
  const KdTree view = KdTree::build(s.positions, s.triangles, aimed(eye, 0.004f));
  ASSERT_LT(view.stats().nodes, plain.stats().nodes);
  for (float scale : {0x1p100f, 0x1p-100f}) {  // powers of two: the scaled soup is exact
    SCOPED_TRACE(testing::Message() << "scale " << scale);
    Soup scaled = s;
    for (glm::vec3& p : scaled.positions) p *= scale;
    const KdTree t = KdTree::build(scaled.positions, scaled.triangles, aimed(eye * scale, 0.004f));
    EXPECT_EQ(t.stats().nodes, view.stats().nodes);
    EXPECT_EQ(t.stats().prim_refs, view.stats().prim_refs);
  }
  const std::vector<RayQuery> rays = random_rays(47, 20000, true);
  std::vector<RayHit> ref(rays.size()), got(rays.size());
  trace_kernels().intersect(plain, rays.data(), ref.data(), rays.size(), true);
  for (const KdBuildOptions& o :
       {aimed(glm::vec3(1e35f, 0.0f, 0.0f), 0.004f), aimed(glm::vec3(0.0f), 0.004f), aimed(eye, 0.004f, 1e30f),
        aimed(eye, 1e30f)}) {
    const KdTree t = KdTree::build(s.positions, s.triangles, o);
    trace_kernels().intersect(t, rays.data(), got.data(), rays.size(), true);
    for (std::size_t i = 0; i < rays.size(); ++i) {
      ASSERT_EQ(std::memcmp(&ref[i], &got[i], sizeof(RayHit)), 0)
          << "eye " << o.footprint_eye.x << " pixels " << o.footprint_pixels << " slope " << o.pixel_slope << ": "
          << test::describe_ray(rays[i]);
    }
  }
}

TEST(KdTree, SubsetBuiltWithIdsReportsThoseIds) {
  // Every third triangle of a sphere on a grid, with ids = their indices in the whole soup (in
  // increasing order, so ties go the same way), against the same subset built without ids:
  // the same tree with the ids mapped in its records, and the same hits; prim_refs() still
  // holds the indices into the subset.
  const Soup s = sphere_and_grid(24);
  std::vector<glm::uvec3> subset;
  std::vector<std::uint32_t> ids;
  for (std::uint32_t t = 1; t < s.triangles.size(); t += 3) {
    subset.push_back(s.triangles[t]);
    ids.push_back(t);
  }
  const std::vector<RayQuery> rays = random_rays(37, 20000, true);
  for (bool watertight : {false, true}) {
    SCOPED_TRACE(test_name(watertight));
    const KdTree plain = KdTree::build(s.positions, subset, with_test(watertight));
    const KdTree with_ids = KdTree::build(s.positions, subset, with_test(watertight), ids);
    ASSERT_EQ(refs_of(plain), refs_of(with_ids));
    ASSERT_FALSE(plain.prim_refs().empty());
    for (std::size_t i = 0; i < plain.prim_refs().size(); ++i) {
      const std::uint32_t index = plain.prim_refs()[i];
      if (index == kLeafBoxRef) continue;
      ASSERT_LT(index, subset.size());
      ASSERT_EQ(plain.leaf_records()[i].wald.id, index);
      ASSERT_EQ(with_ids.leaf_records()[i].wald.id, ids[index]);
    }
    for (bool packets : {true, false}) {
      std::vector<RayHit> a(rays.size()), b(rays.size());
      trace_kernels().intersect(plain, rays.data(), a.data(), rays.size(), packets);
      trace_kernels().intersect(with_ids, rays.data(), b.data(), rays.size(), packets);
      std::size_t hits = 0;
      for (std::size_t i = 0; i < rays.size(); ++i) {
        if (a[i].prim == kNoHit) {
          ASSERT_EQ(b[i].prim, kNoHit) << test::describe_ray(rays[i]);
          continue;
        }
        ++hits;
        ASSERT_EQ(b[i].prim, ids[a[i].prim]) << "packets " << packets << " " << test::describe_ray(rays[i]);
        ASSERT_EQ(b[i].prim % 3, 1u);
        ASSERT_EQ(std::memcmp(&a[i].t, &b[i].t, sizeof(float)), 0) << test::describe_ray(rays[i]);
        ASSERT_EQ(std::memcmp(&a[i].beta, &b[i].beta, sizeof(float)), 0) << test::describe_ray(rays[i]);
        ASSERT_EQ(std::memcmp(&a[i].gamma, &b[i].gamma, sizeof(float)), 0) << test::describe_ray(rays[i]);
      }
      EXPECT_GT(hits, rays.size() / 10) << "packets " << packets;  // 3410 measured
    }
  }
}

TEST(KdTraversal, ZeroDirectionComponentsAndOriginsOnSplitPlanes) {
  // Axis-aligned boxes of triangles; rays along the axes (inverse directions +-inf), starting
  // exactly on the planes the grid puts splits on, with +0 and -0 components.
  const Soup s = sphere_and_grid(16);
  for (bool watertight : {false, true}) {
  SCOPED_TRACE(test_name(watertight));
  const KdTree tree = KdTree::build(s.positions, s.triangles, with_test(watertight));
  std::vector<RayQuery> rays;
  for (const KdNode& n : tree.nodes()) {
    if (n.is_leaf()) continue;
    for (float sgn : {1.0f, -1.0f}) {
      for (float zero : {0.0f, -0.0f}) {
        RayQuery r;
        r.org = glm::vec3(0.1f, 0.05f, 0.2f);
        r.org[n.axis()] = n.split;
        r.dir = glm::vec3(zero);
        r.dir[(n.axis() + 1) % 3] = sgn;
        rays.push_back(r);
        r.dir = glm::vec3(zero);
        r.dir[n.axis()] = sgn;
        rays.push_back(r);
      }
    }
  }
  std::vector<RayHit> hits(rays.size());
  trace_kernels().intersect(tree, rays.data(), hits.data(), rays.size(), true);
  const std::vector<RayHit> ref = brute_force(s, rays);
  // The build clips triangles to node boxes, so planes hug the surface: a ray starting on one
  // can hit at t ~ 1e-3, where Wald's float t (absolute error a few ulps of the unit-sized
  // scene, 1.5e-8 measured at y = -0x1.f257a8p-1) is more than 1e-5 off relatively. Hence
  // the absolute 2e-7 (about 3 ulps of 1.0) beside the relative tolerance.
  const test::HitComparison c = test::compare_hits(s.positions, s.triangles, rays, hits, ref, 1e-5, 1e-3, 2e-7);
  for (std::size_t i : c.examples) ADD_FAILURE() << test::describe_ray(rays[i]);
  // These rays run exactly along rings of sphere vertices (the split planes sit on them), so
  // many graze shared edges, where Wald's test may let a ray through (issue: watertightness).
  // Every interior hit must be found, and ties must be real.
  EXPECT_EQ(c.hit_miss_disagree - c.hit_miss_on_edge, 0u) << c.summary();
  EXPECT_EQ(c.bad_ties, 0u) << c.summary();
  // The watertight test lets no ray through a shared edge: there, hit and miss always agree.
  if (watertight) {
    EXPECT_EQ(c.hit_miss_disagree, 0u) << c.summary();
  }
  std::printf("axis-parallel rays on split planes, %s: %s\n", test_name(watertight), c.summary().c_str());
  }
}

TEST(KdTraversal, OcclusionRespectsTheInterval) {
  std::vector<glm::vec3> p = {{-1, -1, 0}, {1, -1, 0}, {0, 1, 0}};
  std::vector<glm::uvec3> t = {{0, 1, 2}};
  for (bool watertight : {false, true}) {
  SCOPED_TRACE(test_name(watertight));
  const KdTree tree = KdTree::build(p, t, with_test(watertight));
  RayQuery q;
  q.org = {0, 0, 2};
  q.dir = {0, 0, -1};
  std::uint8_t occ = 0;
  q.t_max = 1.5f;
  trace_kernels().occluded(tree, &q, &occ, 1, true);
  EXPECT_EQ(occ, 0);
  q.t_max = 2.5f;
  trace_kernels().occluded(tree, &q, &occ, 1, true);
  EXPECT_EQ(occ, 1);
  q.t_min = 2.1f;
  trace_kernels().occluded(tree, &q, &occ, 1, true);
  EXPECT_EQ(occ, 0);
  }
}

// A closed cube-sphere (welded vertices), rotated off the axes and moved off the origin.
Soup closed_sphere(int quads) {
  const SphereTemplate unit = make_cube_sphere(quads);
  const glm::dmat3 rot = glm::dmat3(glm::dvec3(0.36, 0.48, -0.8), glm::dvec3(-0.8, 0.6, 0.0), glm::dvec3(0.48, 0.64, 0.6));
  Soup s;
  for (const glm::dvec3& p : unit.points) s.positions.emplace_back(glm::dvec3(0.3, -0.2, 0.1) + 1.7 * (rot * p));
  s.triangles = unit.triangles;
  return s;
}

// Rays from inside a closed mesh aimed exactly at its vertices and at points on its edges
// (and from outside, straight in): with a watertight test none may get out without a hit.
// Wald's test lets some through; their number is printed, not asserted.
TEST(KdTraversal, WatertightNeverMissesSharedEdgesAndVertices) {
  const Soup s = closed_sphere(24);
  std::vector<RayQuery> rays;
  std::vector<std::uint8_t> at_vertex;
  const glm::vec3 center(0.3f, -0.2f, 0.1f);
  const glm::vec3 inner[] = {center, center + glm::vec3(0.4f, 0.3f, -0.5f), center + glm::vec3(-0.7f, 0.0f, 0.2f)};
  for (const glm::uvec3& t : s.triangles) {
    for (int e = 0; e < 3; ++e) {
      const glm::vec3 p0 = s.positions[t[e]], p1 = s.positions[t[(e + 1) % 3]];
      for (float f : {0.0f, 0.125f, 0.3f, 0.5f, 0.71f}) {
        const glm::vec3 target = p0 + f * (p1 - p0);
        for (const glm::vec3& o : inner) {
          RayQuery r;
          r.org = o;
          r.dir = target - o;
          rays.push_back(r);
          at_vertex.push_back(f == 0.0f);
        }
        RayQuery out;  // from outside, along the outward radius
        out.org = center + 3.0f * (target - center);
        out.dir = target - out.org;
        rays.push_back(out);
        at_vertex.push_back(f == 0.0f);
      }
    }
  }
  for (bool watertight : {false, true}) {
    const KdTree tree = KdTree::build(s.positions, s.triangles, with_test(watertight));
    for (const Isa isa : compiled_isas()) {
      if (!cpu_supports(isa)) continue;
      for (bool packets : {true, false}) {
        std::vector<RayHit> hits(rays.size());
        std::vector<std::uint8_t> occ(rays.size());
        trace_kernels(isa).intersect(tree, rays.data(), hits.data(), rays.size(), packets);
        trace_kernels(isa).occluded(tree, rays.data(), occ.data(), rays.size(), packets);
        std::size_t missed = 0, missed_at_vertex = 0, unoccluded = 0;
        for (std::size_t i = 0; i < rays.size(); ++i) {
          if (hits[i].prim == kNoHit) {
            ++missed;
            missed_at_vertex += at_vertex[i];
            if (watertight && missed <= 5) ADD_FAILURE() << "missed: " << test::describe_ray(rays[i]);
          }
          if (occ[i] == 0) ++unoccluded;
        }
        std::printf("%s, %s, packets %d: %zu of %zu rays at shared edges and vertices missed (%zu of them at "
                    "vertices), %zu not occluded\n",
                    test_name(watertight), std::string(isa_name(isa)).c_str(), packets ? 1 : 0, missed, rays.size(),
                    missed_at_vertex, unoccluded);
        if (watertight) {
          EXPECT_EQ(missed, 0u) << isa_name(isa) << " packets " << packets;
          EXPECT_EQ(unoccluded, 0u) << isa_name(isa) << " packets " << packets;
        }
      }
    }
  }
}

}  // namespace
}  // namespace rtc
