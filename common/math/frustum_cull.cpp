// FrustumCull: image rectangles whose primary rays all miss a box.
#include "common/math/frustum_cull.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace rtc {

FrustumCull::FrustumCull(const CameraRays& camera, const Aabb& box) : camera_(camera) {
  if (box.empty()) {
    mode_ = Mode::All;
    return;
  }
  const glm::dvec3 lo(box.lo), hi(box.hi);
  for (int a = 0; a < 3; ++a) {
    if (!std::isfinite(lo[a]) || !std::isfinite(hi[a])) return;  // Mode::None
  }
  const glm::dvec3& eye = camera.eye();
  double reach = 0.0;
  for (int c = 0; c < 8; ++c) {
    const glm::dvec3 p((c & 1) ? hi.x : lo.x, (c & 2) ? hi.y : lo.y, (c & 4) ? hi.z : lo.z);
    reach = std::max(reach, glm::length(p - eye));
  }
  // See the class comment: a float ray strays from its exact direction by ~1e-7 of the
  // distance travelled, and the slab test's t by ~2e-6 relative.
  const double margin = 1e-4 * reach;
  const glm::dvec3 glo = lo - glm::dvec3(margin), ghi = hi + glm::dvec3(margin);
  if (glm::all(glm::greaterThanEqual(eye, glo)) && glm::all(glm::lessThanEqual(eye, ghi))) return;
  double x[8], y[8], z[8];
  for (int c = 0; c < 8; ++c) {
    const glm::dvec3 p((c & 1) ? ghi.x : glo.x, (c & 2) ? ghi.y : glo.y, (c & 4) ? ghi.z : glo.z);
    const glm::dvec3 d = p - eye;
    x[c] = glm::dot(d, camera.right());
    y[c] = glm::dot(d, camera.up());
    z[c] = glm::dot(d, camera.forward());
  }
  // Rays have z >= 0 (in front of the eye), so only the box's part there matters: its
  // vertices are the corners with z >= 0 and the points where the edges cross z = 0.
  for (int c = 0; c < 8; ++c) {
    if (z[c] >= 0.0) add_vertex(x[c], y[c], z[c]);
    for (int axis = 0; axis < 3; ++axis) {
      const int other = c | (1 << axis);
      if (other == c || !((z[c] < 0.0 && z[other] > 0.0) || (z[c] > 0.0 && z[other] < 0.0))) continue;
      const double s = z[c] / (z[c] - z[other]);
      add_vertex(x[c] + (x[other] - x[c]) * s, y[c] + (y[other] - y[c]) * s, 0.0);
    }
  }
  if (count_ == 0) {
    mode_ = Mode::All;  // wholly behind the eye
    return;
  }
  mode_ = Mode::Planes;
  if (count_ == 8 && *std::min_element(vz_, vz_ + count_) > 0.0) {
    // Wholly in front of the eye the plane tests below reduce to the box's projected
    // rectangle: x - a0 z < 0 at every corner <=> max(x / z) < a0, and so on. It is kept in
    // image positions (image_a and image_b are affine, a rises with x and b falls with y),
    // which makes a test four comparisons; the inversion's rounding (1e-16 relative) is
    // nothing beside the margin (at least 1e-4 in a and b).
    mode_ = Mode::Rect;
    double a_lo = std::numeric_limits<double>::infinity(), b_lo = a_lo, a_hi = -a_lo, b_hi = -a_lo;
    for (int c = 0; c < count_; ++c) {
      a_lo = std::min(a_lo, vx_[c] / vz_[c]);
      a_hi = std::max(a_hi, vx_[c] / vz_[c]);
      b_lo = std::min(b_lo, vy_[c] / vz_[c]);
      b_hi = std::max(b_hi, vy_[c] / vz_[c]);
    }
    const double a0 = camera.image_a(0.0), a_per_x = camera.image_a(1.0) - a0;
    const double b0 = camera.image_b(0.0), b_per_y = camera.image_b(1.0) - b0;
    x_lo_ = (a_lo - a0) / a_per_x;
    x_hi_ = (a_hi - a0) / a_per_x;
    y_lo_ = (b_hi - b0) / b_per_y;  // b_per_y < 0
    y_hi_ = (b_lo - b0) / b_per_y;
  }
}

void FrustumCull::add_vertex(double x, double y, double z) {
  vx_[count_] = x;
  vy_[count_] = y;
  vz_[count_] = z;
  ++count_;
}

bool FrustumCull::misses(double x0, double y0, double x1, double y1) const {
  if (mode_ == Mode::Rect) return x_hi_ < x0 || x1 < x_lo_ || y_hi_ < y0 || y1 < y_lo_;
  if (mode_ == Mode::None || mode_ == Mode::All) return mode_ == Mode::All;
  // A ray of the rectangle is t (forward + a right + b up), t >= 0, with a in [a0, a1] and b in
  // [b0, b1]; relative to the eye its points have (x, y, z) = t (a, b, 1) in the camera frame,
  // so x - a0 z >= 0, a1 z - x >= 0, y - b0 z >= 0 and b1 z - y >= 0. The part of the box in
  // front of the eye holds no such point when every vertex of it is strictly outside one of
  // these half-spaces.
  const double a0 = camera_.image_a(x0), a1 = camera_.image_a(x1);
  const double b0 = camera_.image_b(y1), b1 = camera_.image_b(y0);  // b falls as y grows
  const auto outside = [this](auto&& value) {
    for (int c = 0; c < count_; ++c) {
      if (!(value(c) < 0.0)) return false;  // NaN: not outside
    }
    return true;
  };
  return outside([&](int c) { return vx_[c] - a0 * vz_[c]; }) || outside([&](int c) { return a1 * vz_[c] - vx_[c]; }) ||
         outside([&](int c) { return vy_[c] - b0 * vz_[c]; }) || outside([&](int c) { return b1 * vz_[c] - vy_[c]; });
}

}  // namespace rtc
