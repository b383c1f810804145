// Self-intersection avoidance for secondary rays: a scale-invariant offset along the normal.
#pragma once

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
[[nodiscard]] glm::vec3 offset_ray_origin(const glm::vec3& p, const glm::vec3& n, float magnitude);

/// Largest absolute coordinate of the three vertices.
[[nodiscard]] float vertex_magnitude(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c);

}  // namespace rtc
