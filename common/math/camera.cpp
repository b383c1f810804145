// CAMERA.md primary rays, computed in double and rounded once.
#include "common/math/camera.h"

#include <cmath>
#include <string>

#include "common/base/error.h"
#include "common/math/det_math.h"

namespace rtc {

std::string camera_problem(const Camera& camera) {
  const auto finite = [](const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); };
  if (!finite(camera.eye) || !finite(camera.look_at) || !finite(camera.up)) {
    return "eye, look_at and up must be finite";
  }
  if (!(camera.vfov_deg > 0.0f && camera.vfov_deg < 180.0f)) {
    return "vfov_deg must be in (0, 180), got " + std::to_string(camera.vfov_deg);
  }
  const glm::dvec3 view = glm::dvec3(camera.look_at) - glm::dvec3(camera.eye);
  if (!(glm::length(view) > 0.0)) return "eye and look_at coincide";
  const glm::dvec3 up(camera.up);
  const double up_length = glm::length(up);
  if (!(up_length > 0.0)) return "up is zero";
  if (!(glm::length(glm::cross(glm::normalize(view), up)) > 1e-12 * up_length)) {
    return "up is parallel to the view direction";
  }
  return {};
}

CameraRays::CameraRays(const Camera& camera, int width, int height) : width_(width), height_(height) {
  if (width <= 0 || height <= 0) {
    throw Error("camera: image size must be positive, got " + std::to_string(width) + "x" +
                std::to_string(height));
  }
  if (const std::string problem = camera_problem(camera); !problem.empty()) throw Error("camera: " + problem);
  eye_ = glm::dvec3(camera.eye);
  forward_ = glm::normalize(glm::dvec3(camera.look_at) - eye_);
  right_ = glm::normalize(glm::cross(forward_, glm::dvec3(camera.up)));
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
