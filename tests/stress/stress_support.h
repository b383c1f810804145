// Stress-test support: a brute-force oracle with the tracer's own float arithmetic, the check
// that every ISA, packets and single rays agree with it bit for bit, and test geometry.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "common/accel/kd_tree.h"
#include "common/accel/trace.h"
#include "common/base/isa.h"
#include "tests/support/hit_compare.h"

namespace rtc::stress {

/// A triangle soup (indices into positions).
struct Soup {
  std::vector<glm::vec3> positions;
  std::vector<glm::uvec3> triangles;
  void add(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c);
  void append(const Soup& other);
};

/// The oracle. Why it is sound: the tracer's contract is that a ray's closest hit is, over
/// ALL triangles, the one Wald's float test (intersect_triangle in kd_traverse.h) accepts with
/// the smallest t in (t_min, t_max), ties in t going to the higher id; the tree only decides
/// which triangles are tested, never how. So a loop over every triangle's record
/// (make_tri_accel, the same function the build uses) with the same float operations in the
/// same order (scalar float, -ffp-contract=off like the kernels) must give the same bits:
/// t, beta, gamma and id. A mismatch means the tree (or traversal) skipped a triangle the ray
/// hits or stopped too early; it cannot be a rounding difference. Whether the float test
/// itself is accurate is checked separately against double precision (check_hit_sanity).
class BruteForce {
 public:
  BruteForce(std::span<const glm::vec3> positions, std::span<const glm::uvec3> triangles);

  [[nodiscard]] RayHit closest(const RayQuery& ray) const;
  [[nodiscard]] bool occluded(const RayQuery& ray) const;
  /// Many rays, the triangles split over threads (10 M triangles x 100 rays in a second or two).
  void closest(std::span<const RayQuery> rays, std::span<RayHit> out) const;
  void occluded(std::span<const RayQuery> rays, std::span<std::uint8_t> out) const;

  [[nodiscard]] const std::vector<TriAccel>& records() const { return records_; }

  /// Every triangle whose float test accepts the ray in (t_min, t_max), nearest first (the
  /// tracer's order: t ascending, then the higher id), each with whether it is a rounding
  /// artefact (EdgeRounding). One pass over all triangles: for the few rays that differ.
  struct Accepted {
    RayHit hit;  ///< t, beta, gamma and id as the float test gives them
    bool artefact = false;
  };
  [[nodiscard]] std::vector<Accepted> accepted(const RayQuery& ray) const;

 private:
  std::vector<TriAccel> records_;  // index = triangle id
  std::vector<glm::vec3> positions_;
  std::vector<glm::uvec3> triangles_;
};

/// Wald's test for one ray and record, exactly as intersect_triangle<1>: the triangle's t and
/// whether it passes the barycentric test (t range not checked here).
struct WaldResult {
  float t = 0.0f, beta = 0.0f, gamma = 0.0f;
  bool inside = false;
};
[[nodiscard]] WaldResult wald_test(const TriAccel& acc, const RayQuery& ray);

/// The ISAs this binary has and this CPU runs, lowest first.
[[nodiscard]] std::vector<Isa> available_isas();

/// Tallies of one agreement check.
struct Agreement {
  std::uint64_t rays = 0;
  std::uint64_t hits = 0;        ///< oracle hits
  std::uint64_t mismatches = 0;  ///< over every ISA x {packets, single} x {closest, occluded}
  /// With EdgeRounding::Explained: differences where every hit the brute force finds before the
  /// kd-tree's is a rounding artefact (see EdgeRounding), counted here, not above.
  std::uint64_t edge_rounding = 0;
  [[nodiscard]] std::string summary() const;
};

/// Traces `rays` (in the given order, so consecutive rays form packets) with intersect and
/// occluded at every available ISA, with packets and single rays, and requires the same bits
/// as the oracle. Each failure is reported (up to a few per call) with the ray in hex floats,
/// the ISA, packet mode, and both answers. `what` names the case in messages.
/// Whether a difference may be explained by the float test's rounding at edges. Wald's test
/// accepts points up to a rounding error outside a triangle: at a vertex shared by thousands of
/// slivers, or for a ray lying in (or grazing) a neighbour's plane, such "hits" belong to
/// triangles the exact ray never touches, so no leaf on the ray's path references them and the
/// kd-tree never tests them, while the brute force does. `Explained` accepts exactly those
/// differences: the kd-tree's hit is one the float test gives (the same t, weights and id) and
/// agrees with its occlusion answer, every triangle the float test accepts before that hit (in
/// the tracer's order; all of them where the kd-tree finds none) is an artefact, and the
/// kd-tree reports no occlusion the brute force does not. An artefact is a triangle whose float
/// weights put the hit within 2^-20 of an edge, or one the exact ray misses: its smallest
/// barycentric weight in double precision (Moller-Trumbore on the float vertices, trusted only
/// where the ray is not nearly parallel to the plane) below -1e-6.
/// The second covers slivers far below a float ulp wide at a vertex shared by thousands, where
/// the float weights carry no information: at ray 133 of the fan case the float test accepts
/// 15 triangles, all of which the exact ray misses (the nearest by -2.4e-3 in weight, 5.4e-5
/// from the sliver), and rejects the two it hits (tests/stress/README.md). A triangle the exact
/// ray hits, or misses by less, that the kd-tree skips before its own hit fails.
enum class EdgeRounding { Exact, Explained };

Agreement expect_agrees_with_brute_force(const KdTree& tree, const BruteForce& oracle,
                                         std::span<const RayQuery> rays, const std::string& what,
                                         EdgeRounding edges = EdgeRounding::Exact);

/// Hit data is never NaN or infinite: t finite and in (t_min, t_max), beta, gamma >= 0,
/// beta + gamma <= 1, and prim a valid id (or a miss with t = t_max). Where the ray is not
/// grazing (|cos| between ray and plane >= 1e-3), t also agrees with the double-precision
/// distance to the plane to 1e-4 relative to the ray's scale. Returns the number of failures
/// (each reported).
std::uint64_t check_hit_sanity(std::span<const glm::vec3> positions, std::span<const glm::uvec3> triangles,
                               std::span<const RayQuery> rays, std::span<const RayHit> hits, const std::string& what);

/// A hit for messages (rays: test::describe_ray in tests/support/hit_compare.h).
[[nodiscard]] std::string describe(const RayHit& hit);

/// Deterministic random rays: origins uniform in `box` enlarged by half its size, directions
/// uniform on the sphere, t in (0, inf).
[[nodiscard]] std::vector<RayQuery> random_rays(std::uint32_t seed, std::size_t count, const Aabb& box);

/// Rays from points inside `box` towards random points on random triangles (nearly all hit).
[[nodiscard]] std::vector<RayQuery> rays_at_triangles(std::uint32_t seed, std::size_t count, const Soup& soup,
                                                      const Aabb& box);

[[nodiscard]] Aabb bounds_of(const Soup& soup);

}  // namespace rtc::stress
