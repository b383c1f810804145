// Axis-aligned bounding boxes.
#pragma once

#include <glm/glm.hpp>
#include <limits>

namespace rtc {

/// An axis-aligned box; empty when lo > hi on any axis (the default).
struct Aabb {
  glm::vec3 lo{std::numeric_limits<float>::infinity()};
  glm::vec3 hi{-std::numeric_limits<float>::infinity()};

  void extend(const glm::vec3& p) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  void extend(const Aabb& b) {
    lo = glm::min(lo, b.lo);
    hi = glm::max(hi, b.hi);
  }
  [[nodiscard]] bool empty() const { return lo.x > hi.x || lo.y > hi.y || lo.z > hi.z; }
  [[nodiscard]] glm::vec3 extent() const { return hi - lo; }
  [[nodiscard]] glm::vec3 center() const { return 0.5f * (lo + hi); }
  /// Surface area; 0 for an empty box.
  [[nodiscard]] float area() const {
    if (empty()) return 0.0f;
    const glm::vec3 e = extent();
    return 2.0f * (e.x * e.y + e.y * e.z + e.z * e.x);
  }
};

}  // namespace rtc
