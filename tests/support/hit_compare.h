// Compares two tracers' closest hits ray by ray: hit/miss agreement, same-triangle distance
// error, and ties (different triangles at the same distance), each tie verified geometrically.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "common/accel/trace.h"
#include "common/math/camera.h"

namespace rtc::test {

struct HitComparison {
  std::uint64_t rays = 0;
  std::uint64_t both_miss = 0;
  std::uint64_t both_hit = 0;
  std::uint64_t hit_miss_disagree = 0;  ///< one hits, the other misses
  /// Of those, rays that pass within edge_eps (barycentric) of an edge of the triangle that
  /// was hit: the cracks of a test that is not watertight. The rest hit a triangle's interior.
  std::uint64_t hit_miss_on_edge = 0;
  std::uint64_t same_prim = 0;
  std::uint64_t same_prim_t_bad = 0;    ///< same triangle, relative t difference > tolerance
  /// Same triangle, difference over tolerance, but ours within 1e-6 of the exact (double)
  /// distance: the error is theirs (rays grazing the plane).
  std::uint64_t same_prim_theirs_off = 0;
  double max_rel_t_same_prim = 0.0;
  std::uint64_t ties = 0;               ///< different triangles, verified tie
  std::uint64_t coplanar_ties = 0;      ///< of those: coplanar overlapping triangles
  std::uint64_t crossing_ties = 0;      ///< of those: surfaces crossing within the tolerance
  /// Different triangles at different distances where the nearer hit lies within edge_eps of
  /// its triangle's edge: one tracer clipped a silhouette edge the other slipped past.
  std::uint64_t edge_grazes = 0;
  std::uint64_t bad_ties = 0;           ///< different triangles, none of the above
  std::vector<std::size_t> examples;    ///< a few offending ray indices

  [[nodiscard]] double hit_miss_agreement() const {
    return rays ? 1.0 - static_cast<double>(hit_miss_disagree) / static_cast<double>(rays) : 1.0;
  }
  /// Rays whose visibility differs only at an edge (hit/miss on an edge, or a graze).
  [[nodiscard]] double edge_disagreement() const {
    return rays ? static_cast<double>(hit_miss_on_edge + edge_grazes) / static_cast<double>(rays) : 0.0;
  }
  /// Ties at shared edges and vertices (not coplanar overlaps or crossings).
  [[nodiscard]] double tie_fraction() const {
    return rays ? static_cast<double>(ties - coplanar_ties - crossing_ties) / static_cast<double>(rays) : 0.0;
  }
  [[nodiscard]] double coplanar_tie_fraction() const {
    return rays ? static_cast<double>(coplanar_ties) / static_cast<double>(rays) : 0.0;
  }
  [[nodiscard]] std::string summary() const;
};

/// Compares `ours` with `theirs` (triangle ids index `triangles`). A tie is two different
/// triangles whose exact (double precision) distances along the ray agree within `rel_tol`
/// and that share a vertex or an edge point (the ray passes within `edge_eps` barycentric of
/// an edge of both), or that are coplanar and overlap where the ray hits, or that cross each
/// other within the tolerance along the ray. Distances agree when |dt| <= rel_tol * |t| + abs_tol.
HitComparison compare_hits(std::span<const glm::vec3> positions, std::span<const glm::uvec3> triangles,
                           std::span<const RayQuery> rays, std::span<const RayHit> ours,
                           std::span<const RayHit> theirs, double rel_tol = 1e-5, double edge_eps = 1e-3,
                           double abs_tol = 0.0);

/// Exact-ish ray/triangle distance in double (Möller-Trumbore); NaN for a miss of the plane.
/// `min_bary` gets the smallest barycentric weight of the hit point (left as it is for NaN),
/// `det` the determinant (e1 . (dir x e2); 0 for a ray parallel to the plane).
double ray_triangle_t(const RayQuery& ray, const glm::vec3& a, const glm::vec3& b, const glm::vec3& c,
                      double* min_bary = nullptr, double* det_out = nullptr);

/// The primary rays through every pixel centre (CAMERA.md), row by row, with (0, inf).
std::vector<RayQuery> pixel_centre_rays(const CameraRays& camera);

/// "x=0x1.8p+0 ..." for failure messages: origin and direction as hex floats.
std::string describe_ray(const RayQuery& ray);

}  // namespace rtc::test
