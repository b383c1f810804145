// CAMERA.md primary rays, computed in double and rounded once.
#include "common/math/camera.h"

#include <cmath>
#include <string>

#include "common/base/error.h"
#include "common/math/det_math.h"

namespace rtc {

CameraRays::CameraRays(const Camera& camera, int width, int height) : width_(width), height_(height) {
  if (width <= 0 || height <= 0) {
    throw Error("camera: image size must be positive, got " + std::to_string(width) + "x" +
                std::to_string(height));
  }
  if (!(camera.vfov_deg > 0.0f && camera.vfov_deg < 180.0f)) {
    throw Error("camera: vfov_deg must be in (0, 180), got " + std::to_string(camera.vfov_deg));
  }
  eye_ = glm::dvec3(camera.eye);
  const glm::dvec3 view = glm::dvec3(camera.look_at) - eye_;
  if (!(glm::length(view) > 0.0)) throw Error("camera: eye and look_at coincide");
  forward_ = glm::normalize(view);
  const glm::dvec3 side = glm::cross(forward_, glm::dvec3(camera.up));
  if (!(glm::length(side) > 1e-12)) throw Error("camera: up is parallel to the view direction");
  right_ = glm::normalize(side);
  up2_ = glm::cross(right_, forward_);
  // det_tan, not std::tan: the same rays on every CPU (see det_math.h).
  h_ = det_tan(camera.vfov_deg * (3.14159265358979323846 / 180.0) / 2.0);
}

RayD CameraRays::ray_double(int x, int y, double sub_x, double sub_y) const {
  const double sx = image_a(x + sub_x);
  const double sy = image_b(y + sub_y);
  return RayD{eye_, glm::normalize(forward_ + sx * right_ + sy * up2_)};
}

Ray CameraRays::ray(int x, int y, double sub_x, double sub_y) const {
  const RayD r = ray_double(x, y, sub_x, sub_y);
  return Ray{glm::vec3(r.origin), glm::vec3(r.dir)};
}

}  // namespace rtc
