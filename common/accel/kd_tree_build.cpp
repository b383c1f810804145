// SAH kd-tree build in O(N log N) (Wald & Havran 2006): three event lists sorted once at the
// root; each node finds its best plane with one sweep per axis and splits its sorted lists in
// linear time into its children's sorted lists. Parallel over subtrees (TBB).
#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <sstream>

#include <fmt/format.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/parallel_sort.h>
#include <tbb/task_arena.h>

#include "common/accel/kd_tree.h"
#include "common/base/error.h"
#include "common/base/timer.h"

namespace rtc {
namespace {

// Event type order within one position does not matter to the sweep below (it counts a whole
// group of equal positions at once), which is what lets children inherit sorted lists whose
// straddling triangles were clamped to the split plane.
enum EventType : std::uint32_t { kEnd = 0, kPlanar = 1, kStart = 2 };

struct Event {
  float pos;
  std::uint32_t code;  // triangle << 2 | type
  [[nodiscard]] std::uint32_t tri() const { return code >> 2; }
  [[nodiscard]] std::uint32_t type() const { return code & 3u; }
};
static_assert(sizeof(Event) == 8);

using EventLists = std::array<std::vector<Event>, 3>;

struct BuildNode {
  int axis = -1;  // -1: leaf
  float split = 0.0f;
  std::unique_ptr<BuildNode> child[2];
  std::vector<std::uint32_t> tris;
};

enum Side : std::uint8_t { kBoth = 0, kLeft = 1, kRight = 2 };

struct SplitChoice {
  int axis = -1;
  float pos = 0.0f;
  bool planar_left = true;
  float cost = std::numeric_limits<float>::infinity();
};

class Builder {
 public:
  Builder(std::size_t triangle_count, const KdBuildOptions& options, int max_depth)
      : options_(options),
        max_depth_(max_depth),
        triangle_count_(triangle_count),
        sides_([triangle_count] { return std::vector<std::uint8_t>(triangle_count, kBoth); }) {}

  std::unique_ptr<BuildNode> build(EventLists events, std::size_t count, const Aabb& box, int depth) {
    auto node = std::make_unique<BuildNode>();
    const SplitChoice split = (depth < max_depth_ && count > static_cast<std::size_t>(options_.leaf_size))
                                  ? find_split(events, count, box)
                                  : SplitChoice{};
    if (split.axis < 0 || !(split.cost < options_.intersection_cost * static_cast<float>(count))) {
      make_leaf(*node, events[0]);
      return node;
    }
    node->axis = split.axis;
    node->split = split.pos;

    EventLists left, right;
    std::size_t left_count = 0, right_count = 0;
    partition(events, split, left, right, left_count, right_count);
    events = EventLists{};  // the parent's lists are no longer needed

    Aabb left_box = box, right_box = box;
    left_box.hi[split.axis] = split.pos;
    right_box.lo[split.axis] = split.pos;

    // Small subtrees are not worth a task; 4096 triangles take well under a millisecond.
    constexpr std::size_t kParallelThreshold = 4096;
    if (left_count + right_count > kParallelThreshold) {
      tbb::parallel_invoke(
          [&] { node->child[0] = build(std::move(left), left_count, left_box, depth + 1); },
          [&] { node->child[1] = build(std::move(right), right_count, right_box, depth + 1); });
    } else {
      node->child[0] = build(std::move(left), left_count, left_box, depth + 1);
      node->child[1] = build(std::move(right), right_count, right_box, depth + 1);
    }
    return node;
  }

 private:
  static void make_leaf(BuildNode& node, const std::vector<Event>& events) {
    for (const Event& e : events) {
      if (e.type() != kEnd) node.tris.push_back(e.tri());  // one start or planar per triangle
    }
    std::sort(node.tris.begin(), node.tris.end());
  }

  [[nodiscard]] float sah(const Aabb& box, int axis, float pos, std::size_t n_left, std::size_t n_right,
                          float inv_area) const {
    Aabb left = box, right = box;
    left.hi[axis] = pos;
    right.lo[axis] = pos;
    float cost = options_.traversal_cost +
                 options_.intersection_cost * inv_area *
                     (left.area() * static_cast<float>(n_left) + right.area() * static_cast<float>(n_right));
    if (n_left == 0 || n_right == 0) cost *= 1.0f - options_.empty_bonus;
    return cost;
  }

  // One sweep over an axis's sorted events (Wald & Havran 2006, section 4.2).
  [[nodiscard]] SplitChoice best_on_axis(const std::vector<Event>& ev, std::size_t count, const Aabb& box, int axis,
                                         float inv_area) const {
    SplitChoice best;
    if (!(box.hi[axis] > box.lo[axis])) return best;
    std::size_t n_left = 0, n_right = count;
    for (std::size_t i = 0; i < ev.size();) {
      const float pos = ev[i].pos;
      std::size_t n_end = 0, n_planar = 0, n_start = 0;
      for (; i < ev.size() && ev[i].pos == pos; ++i) {
        const std::uint32_t t = ev[i].type();
        n_end += t == kEnd;
        n_planar += t == kPlanar;
        n_start += t == kStart;
      }
      n_right -= n_planar + n_end;
      if (pos > box.lo[axis] && pos < box.hi[axis]) {
        const float cost_left = sah(box, axis, pos, n_left + n_planar, n_right, inv_area);
        const float cost_right = sah(box, axis, pos, n_left, n_right + n_planar, inv_area);
        const bool planar_left = cost_left <= cost_right;
        const float cost = planar_left ? cost_left : cost_right;
        if (cost < best.cost) best = SplitChoice{axis, pos, planar_left, cost};
      }
      n_left += n_start + n_planar;
    }
    return best;
  }

  // The best plane over the three axes; big nodes sweep the axes in parallel. Either way the
  // earliest axis wins a tie, so the tree does not depend on the thread count.
  [[nodiscard]] SplitChoice find_split(const EventLists& events, std::size_t count, const Aabb& box) const {
    const float area = box.area();
    if (!(area > 0.0f)) return SplitChoice{};
    const float inv_area = 1.0f / area;
    SplitChoice per_axis[3];
    if (count >= kBigNode) {
      tbb::parallel_for(0, 3, [&](int axis) { per_axis[axis] = best_on_axis(events[axis], count, box, axis, inv_area); });
    } else {
      for (int axis = 0; axis < 3; ++axis) per_axis[axis] = best_on_axis(events[axis], count, box, axis, inv_area);
    }
    SplitChoice best;
    for (const SplitChoice& c : per_axis) {
      if (c.cost < best.cost) best = c;
    }
    return best;
  }

  // Classifies every triangle by its events on the split axis, then splits all three lists.
  // Straddling triangles go to both sides with their split-axis events clamped to the plane:
  // clamping is monotone, so every output list stays sorted and needs no new sort.
  void partition(const EventLists& events, const SplitChoice& split, EventLists& left, EventLists& right,
                 std::size_t& left_count, std::size_t& right_count) {
    // Each thread has its own side table: a triangle that straddles a plane lives in two
    // subtrees that may be partitioned at the same time on different threads. Small nodes
    // never wait on other tasks here, so one thread never interleaves two partitions; big
    // nodes split their three lists in parallel (and so may wait), so they get a table of
    // their own.
    const bool big = left_count_hint(events) >= kBigNode;
    std::vector<std::uint8_t> own;
    if (big) own.assign(triangle_count_, kBoth);
    std::vector<std::uint8_t>& side = big ? own : sides_.local();
    const std::vector<Event>& axis_events = events[split.axis];
    for (const Event& e : axis_events) side[e.tri()] = kBoth;
    for (const Event& e : axis_events) {
      switch (e.type()) {
        case kEnd:
          if (e.pos <= split.pos) side[e.tri()] = kLeft;
          break;
        case kStart:
          if (e.pos >= split.pos) side[e.tri()] = kRight;
          break;
        default:
          if (e.pos < split.pos || (e.pos == split.pos && split.planar_left)) {
            side[e.tri()] = kLeft;
          } else {
            side[e.tri()] = kRight;
          }
      }
    }
    left_count = right_count = 0;
    for (const Event& e : axis_events) {
      if (e.type() == kEnd) continue;  // count each triangle once
      const std::uint8_t s = side[e.tri()];
      left_count += s != kRight;
      right_count += s != kLeft;
    }
    auto split_list = [&](int axis) {
      const std::vector<Event>& ev = events[axis];
      // Count first so each child list is allocated once at its exact size.
      std::size_t n_left = 0, n_right = 0;
      for (const Event& e : ev) {
        const std::uint8_t s = side[e.tri()];
        n_left += s != kRight;
        n_right += s != kLeft;
      }
      std::vector<Event>& l = left[axis];
      std::vector<Event>& r = right[axis];
      l.resize(n_left);
      r.resize(n_right);
      Event* lp = l.data();
      Event* rp = r.data();
      const bool split_axis = axis == split.axis;
      for (const Event& e : ev) {
        switch (side[e.tri()]) {
          case kLeft:
            *lp++ = e;
            break;
          case kRight:
            *rp++ = e;
            break;
          default:
            if (split_axis) {
              *lp++ = Event{std::min(e.pos, split.pos), e.code};
              *rp++ = Event{std::max(e.pos, split.pos), e.code};
            } else {
              *lp++ = e;
              *rp++ = e;
            }
        }
      }
    };
    if (big) {
      tbb::parallel_for(0, 3, split_list);
    } else {
      for (int axis = 0; axis < 3; ++axis) split_list(axis);
    }
  }

  // Triangles in a node: each has one start or planar event per axis list.
  static std::size_t left_count_hint(const EventLists& events) { return (events[0].size() + 1) / 2; }

  // Nodes with at least this many triangles sweep and split their three lists in parallel.
  static constexpr std::size_t kBigNode = 32768;

  const KdBuildOptions& options_;
  int max_depth_;
  std::size_t triangle_count_;
  tbb::enumerable_thread_specific<std::vector<std::uint8_t>> sides_;
};

struct Flattener {
  std::vector<KdNode>& nodes;
  std::vector<std::uint32_t>& refs;
  KdBuildStats& stats;
  const KdBuildOptions& options;
  double inv_root_area;

  void place(const BuildNode& node, std::uint32_t index, const Aabb& box, int depth) {
    stats.max_depth = std::max(stats.max_depth, depth);
    const double rel_area = static_cast<double>(box.area()) * inv_root_area;
    if (node.axis < 0) {
      if (refs.size() + node.tris.size() >= (1u << 30)) {
        throw Error("kd-tree: more than 2^30 triangle references (the 8-byte node format's limit)");
      }
      KdNode leaf;
      leaf.bits = (static_cast<std::uint32_t>(refs.size()) << 2) | 3u;
      leaf.count = static_cast<std::uint32_t>(node.tris.size());
      nodes[index] = leaf;
      refs.insert(refs.end(), node.tris.begin(), node.tris.end());
      ++stats.leaves;
      if (node.tris.empty()) ++stats.empty_leaves;
      stats.sah_cost += options.intersection_cost * rel_area * static_cast<double>(node.tris.size());
      return;
    }
    const auto first = static_cast<std::uint32_t>(nodes.size());
    if (first + 2 >= (1u << 30)) throw Error("kd-tree: more than 2^30 nodes (the 8-byte node format's limit)");
    nodes.resize(nodes.size() + 2);
    KdNode inner;
    inner.bits = (first << 2) | static_cast<std::uint32_t>(node.axis);
    inner.split = node.split;
    nodes[index] = inner;
    stats.sah_cost += options.traversal_cost * rel_area;
    Aabb left_box = box, right_box = box;
    left_box.hi[node.axis] = node.split;
    right_box.lo[node.axis] = node.split;
    place(*node.child[0], first, left_box, depth + 1);
    place(*node.child[1], first + 1, right_box, depth + 1);
  }
};

}  // namespace

TriAccel make_tri_accel(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  // Computed in double, rounded once: the record is as exact as float storage allows.
  const glm::dvec3 A(a), B(b), C(c);
  const glm::dvec3 e1 = B - A, e2 = C - A;
  const glm::dvec3 n = glm::cross(e1, e2);
  TriAccel acc;
  const glm::dvec3 an = glm::abs(n);
  const int k = an.x >= an.y ? (an.x >= an.z ? 0 : 2) : (an.y >= an.z ? 1 : 2);
  if (!(an[k] > 0.0) || !std::isfinite(an[k])) return acc;  // zero area: k = 3, never hits
  const int u = (k + 1) % 3, v = (k + 2) % 3;
  acc.k = static_cast<std::uint32_t>(k);
  acc.n_u = static_cast<float>(n[u] / n[k]);
  acc.n_v = static_cast<float>(n[v] / n[k]);
  acc.n_d = static_cast<float>(glm::dot(n, A) / n[k]);
  // Solve h - A = beta e1 + gamma e2 in the (u, v) projection.
  const double det = e1[u] * e2[v] - e1[v] * e2[u];
  acc.b_nu = static_cast<float>(e2[v] / det);
  acc.b_nv = static_cast<float>(-e2[u] / det);
  acc.b_d = static_cast<float>((A[v] * e2[u] - A[u] * e2[v]) / det);
  acc.c_nu = static_cast<float>(-e1[v] / det);
  acc.c_nv = static_cast<float>(e1[u] / det);
  acc.c_d = static_cast<float>((e1[v] * A[u] - e1[u] * A[v]) / det);
  return acc;
}

std::string KdBuildStats::to_string() const {
  return fmt::format(
      "kd-tree: {} triangles ({} degenerate skipped) in {:.1f} ms, {} nodes, {} leaves ({} empty), "
      "max depth {}, {:.2f} triangles per non-empty leaf, {} refs, SAH cost {:.2f}",
      triangles, degenerate, build_ms, nodes, leaves, empty_leaves, max_depth, mean_tris_per_leaf, prim_refs,
      sah_cost);
}

KdTree KdTree::build(std::span<const glm::vec3> positions, std::span<const glm::uvec3> triangles,
                     const KdBuildOptions& options) {
  Timer timer;
  if (triangles.size() >= (1u << 30)) throw Error("kd-tree: more than 2^30 triangles");
  std::unique_ptr<tbb::global_control> limit;
  if (options.threads > 0) {
    limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                  static_cast<std::size_t>(options.threads));
  }

  KdTree tree;
  tree.stats_.triangles = triangles.size();
  tree.tri_accel_.resize(triangles.size());
  std::vector<Aabb> tri_box(triangles.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, triangles.size(), 4096), [&](const auto& range) {
    for (std::size_t i = range.begin(); i != range.end(); ++i) {
      const glm::uvec3 t = triangles[i];
      RTC_CHECK(t.x < positions.size() && t.y < positions.size() && t.z < positions.size(),
                "kd-tree: triangle index out of range (loaders validate indices)");
      const glm::vec3 a = positions[t.x], b = positions[t.y], c = positions[t.z];
      tree.tri_accel_[i] = make_tri_accel(a, b, c);
      if (tree.tri_accel_[i].k < 3) {
        tri_box[i].extend(a);
        tri_box[i].extend(b);
        tri_box[i].extend(c);
      }
    }
  });

  Aabb root;
  std::size_t count = 0;
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    if (tri_box[i].empty()) continue;
    root.extend(tri_box[i]);
    ++count;
  }
  tree.stats_.degenerate = triangles.size() - count;
  if (count == 0) {
    tree.stats_.build_ms = timer.elapsed_ms();
    return tree;  // empty tree: every ray misses
  }

  EventLists events;
  tbb::parallel_for(0, 3, [&](int axis) {
    std::vector<Event>& ev = events[axis];
    ev.reserve(2 * count);
    for (std::size_t i = 0; i < triangles.size(); ++i) {
      const Aabb& b = tri_box[i];
      if (b.empty()) continue;
      const auto tri = static_cast<std::uint32_t>(i) << 2;
      if (b.lo[axis] == b.hi[axis]) {
        ev.push_back(Event{b.lo[axis], tri | kPlanar});
      } else {
        ev.push_back(Event{b.lo[axis], tri | kStart});
        ev.push_back(Event{b.hi[axis], tri | kEnd});
      }
    }
    std::sort(ev.begin(), ev.end(), [](const Event& x, const Event& y) {
      return x.pos < y.pos || (x.pos == y.pos && x.code < y.code);
    });
  });
  tri_box = {};

  int max_depth = options.max_depth;
  if (max_depth <= 0) max_depth = static_cast<int>(8.0 + 1.3 * std::log2(static_cast<double>(count)));
  max_depth = std::clamp(max_depth, 1, 60);

  Builder builder(triangles.size(), options, max_depth);
  std::unique_ptr<BuildNode> top = builder.build(std::move(events), count, root, 0);

  tree.nodes_.resize(1);
  const float root_area = root.area();
  Flattener flat{tree.nodes_, tree.prim_refs_, tree.stats_, options,
                 root_area > 0.0f ? 1.0 / static_cast<double>(root_area) : 0.0};
  flat.place(*top, 0, root, 0);
  // Destroying the temporary tree recursively is cheap next to building it.
  top.reset();

  tree.stats_.nodes = tree.nodes_.size();
  tree.stats_.prim_refs = tree.prim_refs_.size();
  const std::uint64_t full = tree.stats_.leaves - tree.stats_.empty_leaves;
  tree.stats_.mean_tris_per_leaf = full > 0 ? static_cast<double>(tree.stats_.prim_refs) / static_cast<double>(full) : 0.0;

  // Enlarge the traversal bounds by a few ulps of the largest coordinate so that rays grazing
  // the outermost triangles are not clipped away by rounding in the slab test.
  const glm::vec3 mag = glm::max(glm::abs(root.lo), glm::abs(root.hi));
  const float pad = std::max({mag.x, mag.y, mag.z}) * 4.0f * std::numeric_limits<float>::epsilon();
  tree.bounds_.lo = root.lo - glm::vec3(pad);
  tree.bounds_.hi = root.hi + glm::vec3(pad);
  tree.stats_.build_ms = timer.elapsed_ms();
  return tree;
}

}  // namespace rtc
