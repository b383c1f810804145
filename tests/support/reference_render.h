// The reference render: rtc's shading model (common/render/render_kernels.cpp) traced in double
// precision with brute-force-safe settings, the ground truth the time/error sweep measures
// against. Tests and benchmarks only; slow on purpose where speed would cost accuracy.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include "common/accel/trace.h"
#include "common/image/image.h"
#include "common/render/frame_state.h"

namespace rtc::test {

/// A closest hit in double: t along the ray, barycentric weights of vertices 1 and 2, triangle.
struct RefHit {
  double t = 0.0;
  double beta = 0.0, gamma = 0.0;
  std::uint32_t prim = kNoHit;
};

/// A double-precision BVH over world-space float triangles (converted exactly), traversed with
/// conservative slab tests (Ize 2013: the far distance is widened by 2 gamma_3) and
/// intersected with the watertight test of Woop, Benthin and Wald 2013 in double, so no ray
/// slips between triangles that share an edge. Ties in t go to the higher triangle id, the
/// renderer's rule. Zero-area triangles never hit. Thread-safe after construction.
class ReferenceTracer {
 public:
  ReferenceTracer(std::span<const glm::vec3> positions, std::span<const glm::uvec3> triangles);

  /// Closest hit with t in (t_min, t_max), ignoring triangle `skip` (kNoHit: none), the one a
  /// secondary ray leaves from: a plane cannot be hit twice by a straight ray.
  [[nodiscard]] RefHit intersect(const glm::dvec3& org, const glm::dvec3& dir, double t_min, double t_max,
                                 std::uint32_t skip = kNoHit) const;
  /// Any hit with t in (t_min, t_max), ignoring `skip`.
  [[nodiscard]] bool occluded(const glm::dvec3& org, const glm::dvec3& dir, double t_min, double t_max,
                              std::uint32_t skip = kNoHit) const;

  [[nodiscard]] double build_ms() const { return build_ms_; }
  [[nodiscard]] std::size_t node_count() const { return nodes_.size(); }

 private:
  struct Node {
    glm::dvec3 lo, hi;
    std::uint32_t first = 0;  ///< leaf: first index into order_; inner: left child (right = +1)
    std::uint32_t count = 0;  ///< triangles in a leaf; 0 for an inner node
  };
  template <bool kAny>
  RefHit trace(const glm::dvec3& org, const glm::dvec3& dir, double t_min, double t_max, std::uint32_t skip) const;

  std::vector<glm::dvec3> verts_;  ///< 3 per triangle, by triangle id
  std::vector<std::uint32_t> order_;
  std::vector<Node> nodes_;
  double build_ms_ = 0.0;
};

/// Settings of the reference: deep reflections and no ray-weight cutoff by default.
struct ReferenceOptions {
  int max_depth = 64;       ///< the renderer's own limit (check_render_settings)
  double min_weight = 0.0;  ///< reflections of any weight are traced
};

struct ReferenceStats {
  double ms = 0.0;
  std::uint64_t primary = 0, shadow = 0, reflection = 0;
};

/// Renders the frame of `fs` (camera, spp sample positions, lights, materials, background,
/// ambient: everything but the reflection limits, which come from `options`) with rtc's
/// Whitted/Phong shading evaluated in double: camera rays in double, hit points from double
/// barycentrics, secondary rays offset 2^-40 times the triangle's magnitude (the renderer uses
/// 2^-16 in float) and never hitting the triangle they leave. RGBA float, alpha 1; parallel
/// over rows (TBB).
[[nodiscard]] Image reference_render(const FrameState& fs, const ReferenceTracer& tracer,
                                     const ReferenceOptions& options = {}, ReferenceStats* stats = nullptr);

/// How far an image is from a reference, measured on what a viewer sees: each RGB channel
/// clamped to [0, 1] and sRGB-encoded (continuous, no quantisation) before comparing.
struct ImageError {
  double rmse = 0.0;
  double psnr_db = 0.0;          ///< 20 log10(1 / rmse); +inf when identical
  double max_abs = 0.0;          ///< largest channel difference
  double pct_over_1_255 = 0.0;   ///< % of pixels with any channel differing by more than 1/255
  std::uint64_t non_finite = 0;  ///< NaN or Inf values anywhere in `image` (RGBA, depth, normal)
};

/// A linear channel value as the error measures see it: clamped to [0, 1], sRGB-encoded.
[[nodiscard]] double display_value(float linear);

/// Throws rtc::Error when the sizes differ. `per_pixel` (optional) gets each pixel's largest
/// channel difference, row by row (the error map).
[[nodiscard]] ImageError image_error(const Image& image, const Image& reference,
                                     std::vector<double>* per_pixel = nullptr);

/// Non-finite values anywhere in the image (RGBA, depth where not +inf background, normal).
[[nodiscard]] std::uint64_t count_non_finite(const Image& image);

}  // namespace rtc::test
