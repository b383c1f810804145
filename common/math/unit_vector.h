// Normalising float vectors whose squared length a float cannot hold.
#pragma once

#include <cmath>
#include <limits>

#include <glm/glm.hpp>

namespace rtc {

/// Whether a float squared length normalises well in float: neither overflowed (a vector longer
/// than about 1.8e19) nor below the normal floats (shorter than about 1.1e-19: underflowed or
/// short of bits). NaN is not.
inline bool normal_float_length2(float length2) {
  return length2 >= std::numeric_limits<float>::min() && length2 <= std::numeric_limits<float>::max();
}

/// `a` normalised in double, rounded once; `fallback` for a zero or non-finite vector. For the
/// vectors normal_float_length2 turns away; rare, so out of line.
[[gnu::cold, gnu::noinline]] inline glm::vec3 unit_in_double_or(const glm::vec3& a, const glm::vec3& fallback) {
  const glm::dvec3 d(a);
  const double length = glm::length(d);
  if (!(length > 0.0) || !std::isfinite(length)) return fallback;
  return glm::vec3(d / length);
}

}  // namespace rtc
