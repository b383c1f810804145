// Embree 3 as the oracle of which triangle each ray hits, and as the speed yardstick.
// Linked only by tests and benchmarks, never by the renderer.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include <glm/glm.hpp>

#include "common/accel/trace.h"

namespace rtc::test {

/// Which Embree traversal to use for a stream of rays.
enum class EmbreeMode { Single = 1, Packet4 = 4, Packet8 = 8, Packet16 = 16 };

/// An Embree scene over the same triangle arrays the kd-tree gets. Not copyable.
class EmbreeScene {
 public:
  /// `robust`: RTC_SCENE_FLAG_ROBUST; `high_quality`: RTC_BUILD_QUALITY_HIGH.
  EmbreeScene(std::span<const glm::vec3> positions, std::span<const glm::uvec3> triangles,
              bool robust = false, bool high_quality = false);
  ~EmbreeScene();
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;

  [[nodiscard]] double build_ms() const { return build_ms_; }
  /// Whether this Embree build supports the packet width (rtcIntersect16 needs AVX-512).
  [[nodiscard]] bool supports(EmbreeMode mode) const;

  /// Closest hits for rays in packets of the mode's width (consecutive rays form a packet).
  void intersect(const RayQuery* rays, RayHit* hits, std::size_t count, EmbreeMode mode) const;
  /// Occlusion; out[i] = 1 when ray i hits anything in (t_min, t_max).
  void occluded(const RayQuery* rays, std::uint8_t* out, std::size_t count, EmbreeMode mode) const;

  [[nodiscard]] static std::string mode_name(EmbreeMode mode);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  double build_ms_ = 0;
};

}  // namespace rtc::test
