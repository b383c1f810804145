// Self-intersection avoidance for secondary rays: a scale-invariant offset along the normal.
#pragma once

#include <algorithm>
#include <limits>

#include <glm/glm.hpp>

namespace rtc {

/// Moves hit point `p` off its surface along the unit geometric normal `n` (pointing to the
/// side the new ray leaves from) by 2^-16 times `magnitude`, the largest absolute vertex
/// coordinate of the hit triangle: about 128 ulps of the numbers the hit point and the next
/// ray's triangle tests are computed from. In the spirit of Wächter & Binder 2019 (Ray
/// Tracing Gems ch. 6), whose integer-ulp step is relative to each coordinate of p; ours is
/// relative to the triangle's magnitude, so it also holds where p's coordinates cross zero
/// (their fixed 2^-16 step near the origin is too large for scenes smaller than ~1e-3).
/// `p` should come from barycentric interpolation, not org + t dir.
[[nodiscard]] inline glm::vec3 offset_ray_origin(const glm::vec3& p, const glm::vec3& n, float magnitude) {
  // 2^-16 = 128 float ulps of `magnitude`; the smallest normal float keeps a scene that sits
  // exactly at the origin (magnitude 0 cannot happen for a triangle of non-zero area) moving.
  const float step = std::max(magnitude * (1.0f / 65536.0f), std::numeric_limits<float>::min());
  return {p.x + n.x * step, p.y + n.y * step, p.z + n.z * step};
}

/// Largest absolute coordinate of the three vertices.
[[nodiscard]] inline float vertex_magnitude(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  const glm::vec3 m = glm::max(glm::max(glm::abs(a), glm::abs(b)), glm::abs(c));
  return std::max({m.x, m.y, m.z});
}

}  // namespace rtc
