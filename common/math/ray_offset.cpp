// Scale-invariant ray origin offset.
#include "common/math/ray_offset.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace rtc {

glm::vec3 offset_ray_origin(const glm::vec3& p, const glm::vec3& n, float magnitude) {
  // 2^-16 = 128 float ulps of `magnitude`; the smallest normal float keeps a scene that sits
  // exactly at the origin (magnitude 0 cannot happen for a triangle of non-zero area) moving.
  const float step = std::max(magnitude * (1.0f / 65536.0f), std::numeric_limits<float>::min());
  return {p.x + n.x * step, p.y + n.y * step, p.z + n.z * step};
}

float vertex_magnitude(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  const glm::vec3 m = glm::max(glm::max(glm::abs(a), glm::abs(b)), glm::abs(c));
  return std::max({m.x, m.y, m.z});
}

}  // namespace rtc
