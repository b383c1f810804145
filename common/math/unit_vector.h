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

/// `d` normalised, rounded once to float; `fallback` for a zero or non-finite vector.
inline glm::vec3 unit_rounded_or(const glm::dvec3& d, const glm::vec3& fallback) {
  const double length = glm::length(d);
  if (!(length > 0.0) || !std::isfinite(length)) return fallback;
  return glm::vec3(d / length);
}

/// `a` normalised in double, rounded once; `fallback` for a zero or non-finite vector. For the
/// vectors normal_float_length2 turns away; rare, so out of line.
[[gnu::cold, gnu::noinline]] inline glm::vec3 unit_in_double_or(const glm::vec3& a, const glm::vec3& fallback) {
  return unit_rounded_or(glm::dvec3(a), fallback);
}

}  // namespace rtc
