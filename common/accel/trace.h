// Ray streams through the kd-tree for code that is not compiled per ISA (benchmarks, tests,
// tools): closest-hit and occlusion queries with run-time ISA dispatch.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <string_view>

#include <glm/glm.hpp>

#include "common/accel/kd_tree.h"
#include "common/accel/shadow_order.h"
#include "common/base/isa.h"

namespace rtc {

/// One ray with its valid interval (t_min, t_max). 32 bytes.
struct RayQuery {
  glm::vec3 org{0.0f};
  float t_min = 0.0f;
  glm::vec3 dir{0.0f, 0.0f, 1.0f};
  float t_max = std::numeric_limits<float>::infinity();
};

inline constexpr std::uint32_t kNoHit = 0xFFFFFFFFu;

/// Closest hit: t, barycentric weights of vertices 1 and 2, triangle id (kNoHit for a miss,
/// then t = t_max).
struct RayHit {
  float t = 0.0f;
  float beta = 0.0f, gamma = 0.0f;
  std::uint32_t prim = kNoHit;
};

/// Stream entry points of one ISA. With packets, every `packet_width` consecutive rays form a
/// packet (give them as 2x2 pixel blocks for coherence); without, each ray is traced alone by
/// the N = 1 kernel. Both give the same bits. Thread-safe. `occluded` walks near-first (Auto
/// without a tally); `occluded_in_order` takes the order (the answers are the same in every
/// order) and, for Auto, a tally shared by the calls (thread-safe) that each call's choice
/// learns from and adds to (ShadowOrderChooser; without one, Auto is near-first).
struct TraceKernels {
  Isa isa = Isa::Sse42;
  int packet_width = 4;
  void (*intersect)(const KdTree& tree, const RayQuery* rays, RayHit* hits, std::size_t count,
                    bool use_packets) = nullptr;
  void (*occluded)(const KdTree& tree, const RayQuery* rays, std::uint8_t* occluded, std::size_t count,
                   bool use_packets) = nullptr;
  void (*occluded_in_order)(const KdTree& tree, const RayQuery* rays, std::uint8_t* occluded, std::size_t count,
                            bool use_packets, ShadowOrder order, ShadowOrderTally* tally) = nullptr;
};

/// Recomputes the distance of each hit in double precision from its triangle's vertices
/// (t = n.(a - o) / n.d), rounded once to float. The float test's t is as good as float allows
/// for most rays but, for rays grazing a triangle's plane, loses up to ~1e-5 relative to
/// cancellation; the hit triangle and barycentrics are unchanged. Deterministic.
void refine_hit_distances(std::span<const glm::vec3> positions, std::span<const glm::uvec3> triangles,
                          const RayQuery* rays, RayHit* hits, std::size_t count);

/// The same for one ray and triangle (a, b, c).
[[nodiscard]] float refined_distance(const glm::vec3& org, const glm::vec3& dir, const glm::vec3& a,
                                     const glm::vec3& b, const glm::vec3& c, float fallback);

/// Kernels for `isa`; throws rtc::Error when it is not compiled in or the CPU lacks it.
[[nodiscard]] const TraceKernels& trace_kernels(Isa isa);
/// Kernels for best_isa().
[[nodiscard]] const TraceKernels& trace_kernels();

}  // namespace rtc
