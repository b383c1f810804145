// Conservative culling of primary rays: which rectangles of the image see nothing of a box.
#pragma once

#include "common/math/aabb.h"
#include "common/math/camera.h"

namespace rtc {

/// Answers, for a rectangle of image positions, whether every primary ray through it misses a
/// box (the scene's bounds) so clearly that the ray's float slab test against the box, as the
/// kd-tree traversal does it, finds an empty segment: such rays need not be traced at all.
///
/// The camera's rays through a rectangle lie in the cone of its four corner rays (their
/// directions are affine in the image position before normalisation, CameraRays), so the
/// rectangle sees nothing of the box when the box's part in front of the eye lies wholly
/// outside one of the cone's four side planes. The test runs in double on the box grown by
/// 1e-4 of its farthest corner's distance from the eye: that covers the float rays' rounding
/// (2^-24 relative per direction component, so ~1e-7 of the distance travelled) and the slab
/// test's (a few ulps of t, and the watertight traversal's 2^-20 reach) with a wide margin.
/// Immutable; thread-safe.
class FrustumCull {
 public:
  /// Culls nothing.
  FrustumCull() = default;
  /// An empty `box` (no triangles) culls everything; a box that is not finite, or one around
  /// the eye, culls nothing.
  FrustumCull(const CameraRays& camera, const Aabb& box);

  /// True when every ray through image positions (x, y) in [x0, x1] x [y0, y1] misses the box
  /// (positions are pixel + sample offset, row 0 at the top: pixels [px, px + w) with any
  /// offsets in [0, 1) lie in [px, px + w]).
  [[nodiscard]] bool misses(double x0, double y0, double x1, double y1) const;

  /// Whether misses() can ever answer true.
  [[nodiscard]] bool active() const { return mode_ != Mode::None; }

 private:
  enum class Mode { None, All, Rect, Planes };
  void add_vertex(double x, double y, double z);

  Mode mode_ = Mode::None;
  // The vertices of the grown box's part in front of the eye (z >= 0), relative to the eye in
  // the camera frame (right, up, forward): corners, and edges crossing z = 0.
  double vx_[20] = {}, vy_[20] = {}, vz_[20] = {};
  int count_ = 0;
  // Mode::Rect (the whole box in front of the eye): its projection lies in image positions
  // [x_lo_, x_hi_] x [y_lo_, y_hi_].
  double x_lo_ = 0.0, x_hi_ = 0.0, y_lo_ = 0.0, y_hi_ = 0.0;
  CameraRays camera_{Camera{}, 1, 1};  // for image_a and image_b
};

}  // namespace rtc
