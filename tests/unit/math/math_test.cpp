// Deterministic elementary functions against libm, the CAMERA.md ray convention, and the
// scale-invariant ray offset.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "common/base/error.h"
#include "common/math/camera.h"
#include "common/math/det_math.h"
#include "common/math/ray_offset.h"

namespace rtc {
namespace {

TEST(DetMath, Exp2AndLog2MatchLibm) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> y(-140.0, 120.0), x(1e-30, 1e30);
  for (int i = 0; i < 100000; ++i) {
    const double a = y(rng);
    EXPECT_NEAR(det_exp2(a) / std::exp2(a), 1.0, 1e-14) << a;
    const double b = x(rng);
    EXPECT_NEAR(det_log2(b), std::log2(b), 1e-13) << b;
  }
  EXPECT_EQ(det_exp2(0.0), 1.0);
  EXPECT_EQ(det_exp2(10.0), 1024.0);
  EXPECT_EQ(det_log2(0.0), -INFINITY);
  EXPECT_TRUE(std::isnan(det_log2(-1.0)));
}

TEST(DetMath, PowfMatchesLibmToAFloatUlpOrTwo) {
  std::mt19937 rng(2);
  std::uniform_real_distribution<float> x(0.0f, 1.0f), e(0.0f, 2000.0f);
  for (int i = 0; i < 100000; ++i) {
    const float a = x(rng), b = e(rng);
    const float want = std::pow(a, b), got = det_powf(a, b);
    EXPECT_NEAR(got, want, 2.5e-7f * want + 1e-37f) << a << "^" << b;
  }
  EXPECT_EQ(det_powf(0.5f, 0.0f), 1.0f);
  EXPECT_EQ(det_powf(0.0f, 3.0f), 0.0f);
  EXPECT_EQ(det_powf(1.0f, 1e5f), 1.0f);
  EXPECT_EQ(det_powf(0.999f, 1e5f), std::pow(0.999f, 1e5f));  // e^-100: a subnormal float
  EXPECT_EQ(det_powf(0.5f, 1e5f), 0.0f);
}

TEST(DetMath, TanMatchesLibm) {
  for (double deg = 0.5; deg < 179.6; deg += 0.5) {
    const double x = deg * (3.14159265358979323846 / 360.0);
    EXPECT_NEAR(det_tan(x) / std::tan(x), 1.0, 1e-13) << deg;
  }
}

TEST(Camera, FollowsCameraMd) {
  Camera c;
  c.eye = {0, 0, 5};
  c.look_at = {0, 0, 0};
  c.up = {0, 1, 0};
  c.vfov_deg = 90.0f;
  const CameraRays rays(c, 4, 2);
  // Pixel centres: sx = (2 (x + 0.5) / W - 1) h (W / H), sy = (1 - 2 (y + 0.5) / H) h, h = 1.
  const Ray r = rays.ray(3, 0);
  const glm::dvec3 want = glm::normalize(glm::dvec3(0.75 * 2.0, 0.5, -1.0));
  EXPECT_FLOAT_EQ(r.dir.x, static_cast<float>(want.x));
  EXPECT_FLOAT_EQ(r.dir.y, static_cast<float>(want.y));
  EXPECT_FLOAT_EQ(r.dir.z, static_cast<float>(want.z));
  EXPECT_EQ(r.origin, c.eye);
}

TEST(Camera, DegenerateCamerasAreErrors) {
  Camera c;
  c.eye = c.look_at = {1, 2, 3};
  EXPECT_THROW(CameraRays(c, 4, 4), Error);
  c.eye = {0, 5, 0};
  c.look_at = {0, 0, 0};
  c.up = {0, 1, 0};
  EXPECT_THROW(CameraRays(c, 4, 4), Error);
  c.up = {0, 0, 1};
  c.vfov_deg = 180.0f;
  EXPECT_THROW(CameraRays(c, 4, 4), Error);
  c.vfov_deg = 40.0f;
  EXPECT_THROW(CameraRays(c, 0, 4), Error);
}

TEST(RayOffset, ScalesWithTheTriangle) {
  for (float scale : {1e-6f, 1e-3f, 1.0f, 1e3f, 1e6f}) {
    const glm::vec3 p(0.3f * scale, 0.0f, -0.2f * scale);
    const glm::vec3 q = offset_ray_origin(p, glm::vec3(0, 1, 0), scale);
    EXPECT_GT(q.y, 0.0f);
    EXPECT_NEAR(q.y / scale, 1.0f / 65536.0f, 1e-9f);
    EXPECT_EQ(q.x, p.x);
  }
}

}  // namespace
}  // namespace rtc
