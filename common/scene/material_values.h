// Checks for the numbers a mesh file gives a material (MTL Kd/Ks/Ke/Ns/d/Tr, NFF f, glTF factors):
// a NaN or infinite value would give NaN pixels, a negative shininess or colour too (the Phong
// term raises a cosine to the shininess and weights reflections by the specular colour). An
// opacity outside [0, 1] means nothing (a scene.json refuses it).
#pragma once

#include <cstdint>
#include <string_view>

#include <glm/glm.hpp>

namespace rtc {

/// `color` unless something is wrong with it: a non-finite component throws
/// rtc::Error("file:line: <what> (r, g, b) is not finite"); negative components become 0 with
/// one warning naming file:line, `what` and the value. Line 0 leaves the line out.
[[nodiscard]] glm::vec3 checked_color(const glm::vec3& color, std::string_view what,
                                      std::string_view file, std::uint64_t line);

/// `shininess` unless something is wrong with it: non-finite throws rtc::Error naming file:line,
/// `what` and the value; negative becomes 0 with one warning.
[[nodiscard]] float checked_shininess(float shininess, std::string_view what,
                                      std::string_view file, std::uint64_t line);

/// `opacity` unless something is wrong with it: non-finite throws rtc::Error naming file:line,
/// `what` and the value; outside [0, 1] it is clamped into it with one warning.
[[nodiscard]] float checked_opacity(float opacity, std::string_view what, std::string_view file,
                                    std::uint64_t line);

}  // namespace rtc
