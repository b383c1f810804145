// The pinhole camera of ../shared/scenes/CAMERA.md and its primary rays.
#pragma once

#include <string>

#include <glm/glm.hpp>

namespace rtc {

/// Camera as in view.json: eye, look_at, up, vertical field of view in degrees.
struct Camera {
  glm::vec3 eye{0.0f, 0.0f, 1.0f};
  glm::vec3 look_at{0.0f, 0.0f, 0.0f};
  glm::vec3 up{0.0f, 1.0f, 0.0f};
  float vfov_deg = 45.0f;

  bool operator==(const Camera&) const = default;
};

/// A ray in world space; dir need not be normalised for secondary rays.
struct Ray {
  glm::vec3 origin{0.0f};
  glm::vec3 dir{0.0f, 0.0f, 1.0f};
};

/// A ray in double precision (the reference renderer's).
struct RayD {
  glm::dvec3 origin{0.0};
  glm::dvec3 dir{0.0, 0.0, 1.0};
};

/// Why `camera` cannot make rays, or "" when it can: a non-finite eye, look_at or up, eye and
/// look_at that coincide, an up that is zero or parallel to the view direction (the sine of
/// their angle at most 1e-12; up's length does not matter), or vfov_deg outside (0, 180). In
/// double, so no coordinate the float range holds overflows or underflows here. The scene
/// loaders and CameraRays ask the same question.
[[nodiscard]] std::string camera_problem(const Camera& camera);

/// Precomputed camera frame for a W x H image. Rays follow CAMERA.md exactly; the frame and
/// each ray are computed in double and rounded once to float, so every tracer (rtc, the
/// Embree oracle) that uses this class gets bit-identical rays. Thread-safe after construction.
class CameraRays {
 public:
  /// Throws rtc::Error for a degenerate camera (eye == look_at, up parallel to the view
  /// direction, vfov outside (0, 180)) or an empty image.
  CameraRays(const Camera& camera, int width, int height);

  /// Ray through image position (x + sub_x, y + sub_y), row 0 at the top; sub = 0.5 is the
  /// pixel centre of CAMERA.md.
  [[nodiscard]] Ray ray(int x, int y, double sub_x = 0.5, double sub_y = 0.5) const;
  /// The same ray before rounding to float (unit direction in double).
  [[nodiscard]] RayD ray_double(int x, int y, double sub_x = 0.5, double sub_y = 0.5) const;

  [[nodiscard]] int width() const { return width_; }
  [[nodiscard]] int height() const { return height_; }

  /// The frame the rays are made from, in double: ray(x, y, sub_x, sub_y) leaves eye along
  /// normalize(forward + a right + b up) with a = image_a(x + sub_x) and b = image_b(y + sub_y),
  /// both affine in the image position, so the rays through an image rectangle lie in the cone
  /// of its four corner rays.
  [[nodiscard]] const glm::dvec3& eye() const { return eye_; }
  [[nodiscard]] const glm::dvec3& forward() const { return forward_; }
  [[nodiscard]] const glm::dvec3& right() const { return right_; }
  [[nodiscard]] const glm::dvec3& up() const { return up2_; }
  [[nodiscard]] double image_a(double x) const {
    return (2.0 * x / width_ - 1.0) * h_ * (static_cast<double>(width_) / height_);
  }
  [[nodiscard]] double image_b(double y) const { return (1.0 - 2.0 * y / height_) * h_; }

 private:
  glm::dvec3 eye_, forward_, right_, up2_;
  double h_ = 1.0;
  int width_ = 1, height_ = 1;
};

}  // namespace rtc
