// Material number checks shared by the mesh loaders.
#include "common/scene/material_values.h"

#include <cmath>
#include <string>

#include <fmt/format.h>

#include "common/base/error.h"
#include "common/base/log.h"

namespace rtc {

glm::vec3 checked_color(const glm::vec3& color, std::string_view what, std::string_view file,
                        std::uint64_t line) {
  const std::string text = fmt::format("({}, {}, {})", color.r, color.g, color.b);
  if (!std::isfinite(color.r) || !std::isfinite(color.g) || !std::isfinite(color.b)) {
    throw_at(file, line, fmt::format("{} {} is not finite", what, text));
  }
  if (color.r >= 0.0f && color.g >= 0.0f && color.b >= 0.0f) return color;
  spdlog::warn("{}",
               at_location(file, line, fmt::format("negative {} {} clamped to 0", what, text)));
  return glm::max(color, glm::vec3(0.0f));
}

float checked_shininess(float shininess, std::string_view what, std::string_view file,
                        std::uint64_t line) {
  if (!std::isfinite(shininess)) {
    throw_at(file, line, fmt::format("{} {} is not finite", what, shininess));
  }
  if (shininess >= 0.0f) return shininess;
  spdlog::warn("{}", at_location(file, line,
                                 fmt::format("negative {} {} clamped to 0", what, shininess)));
  return 0.0f;
}

float checked_opacity(float opacity, std::string_view what, std::string_view file, std::uint64_t line) {
  if (!std::isfinite(opacity)) {
    throw_at(file, line, fmt::format("{} {} is not finite", what, opacity));
  }
  if (opacity >= 0.0f && opacity <= 1.0f) return opacity;
  const float clamped = opacity < 0.0f ? 0.0f : 1.0f;
  spdlog::warn("{}", at_location(file, line, fmt::format("{} {} is outside [0, 1]: taken as {}", what, opacity, clamped)));
  return clamped;
}

}  // namespace rtc
