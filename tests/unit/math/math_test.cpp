// Deterministic elementary functions against libm, the CAMERA.md ray convention, and the
// scale-invariant ray offset.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
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

/// |got - want| <= tolerance |want|, printed as hex floats when it fails.
::testing::AssertionResult RelativelyNear(double got, double want, double tolerance, double x) {
  if (std::abs(got - want) <= tolerance * std::abs(want)) return ::testing::AssertionSuccess();
  char text[160];
  std::snprintf(text, sizeof text, "x = %a: got %a, libm %a (relative error %.3g)", x, got, want,
                (got - want) / want);
  return ::testing::AssertionFailure() << text;
}

TEST(DetMath, SinAndCosMatchLibm) {
  const unsigned seed = 3;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> small(-4.0, 4.0), medium(-1e4, 1e4), large(-8e5, 8e5);
  for (int i = 0; i < 100000; ++i) {
    for (const double x : {small(rng), medium(rng), large(rng)}) {
      ASSERT_TRUE(RelativelyNear(det_sin(x), std::sin(x), 1e-14, x)) << "seed " << seed;
      ASSERT_TRUE(RelativelyNear(det_cos(x), std::cos(x), 1e-14, x)) << "seed " << seed;
    }
  }
  EXPECT_EQ(det_sin(0.0), 0.0);
  EXPECT_EQ(det_cos(0.0), 1.0);
  EXPECT_TRUE(std::signbit(det_sin(-0.0)));
  EXPECT_EQ(det_sin(1e-300), 1e-300);
  EXPECT_TRUE(std::isnan(det_sin(INFINITY)));
  EXPECT_TRUE(std::isnan(det_cos(-INFINITY)));
  EXPECT_TRUE(std::isnan(det_sin(NAN)));
}

TEST(DetMath, SinAndCosKeepTheirDigitsNearMultiplesOfHalfPi) {
  // The doubles nearest k pi/2 (and their neighbours): sin or cos there is 1e-13..1e-17, all
  // of it in the reduction's low bits.
  for (int k = 1; k <= 6400; ++k) {
    const double near = static_cast<double>(k) * 1.57079632679489661923;
    for (const double x : {near, std::nextafter(near, 0.0), std::nextafter(near, 1e9), -near}) {
      ASSERT_TRUE(RelativelyNear(det_sin(x), std::sin(x), 1e-14, x)) << "k = " << k;
      ASSERT_TRUE(RelativelyNear(det_cos(x), std::cos(x), 1e-14, x)) << "k = " << k;
    }
  }
}

TEST(DetMath, SinAndCosOfHugeArgumentsStayBounded) {
  for (const double x : {1e6, -3.5e7, 1e12, 1e100, -1e308}) {
    const double s = det_sin(x), c = det_cos(x);
    EXPECT_LE(std::abs(s), 1.0) << x;
    EXPECT_NEAR(s * s + c * c, 1.0, 1e-14) << x;
    if (std::abs(x) < 1e13) {
      EXPECT_NEAR(s, std::sin(x), std::abs(x) * 0x1p-50) << x;
    }
  }
}

TEST(DetMath, Atan2AndAcosMatchLibm) {
  const unsigned seed = 4;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0), exponent(-40.0, 40.0);
  for (int i = 0; i < 100000; ++i) {
    const double y = unit(rng) * std::exp2(exponent(rng));
    const double x = unit(rng) * std::exp2(exponent(rng));
    ASSERT_TRUE(RelativelyNear(det_atan2(y, x), std::atan2(y, x), 1e-14, y))
        << "x = " << std::hexfloat << x << ", seed " << seed;
    const double c = unit(rng);
    ASSERT_TRUE(RelativelyNear(det_acos(c), std::acos(c), 1e-14, c)) << "seed " << seed;
    // Near +-1, where acos is steep.
    const double edge = std::copysign(1.0 - std::exp2(-std::abs(exponent(rng)) - 10.0), c);
    ASSERT_TRUE(RelativelyNear(det_acos(edge), std::acos(edge), 1e-14, edge)) << "seed " << seed;
  }
  constexpr double kInf = std::numeric_limits<double>::infinity();
  for (const double y : {0.0, -0.0, 1.0, -1.0, kInf, -kInf}) {
    for (const double x : {0.0, -0.0, 1.0, -1.0, kInf, -kInf}) {
      EXPECT_TRUE(RelativelyNear(det_atan2(y, x), std::atan2(y, x), 1e-15, y)) << x;
      EXPECT_EQ(std::signbit(det_atan2(y, x)), std::signbit(std::atan2(y, x))) << y << " " << x;
    }
  }
  EXPECT_EQ(det_acos(1.0), 0.0);
  EXPECT_TRUE(std::isnan(det_acos(1.0000001)));
  EXPECT_TRUE(std::isnan(det_atan2(NAN, 1.0)));
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

TEST(Camera, ProblemsAreJudgedInDoubleAndUpByItsDirectionOnly) {
  Camera c;
  c.eye = {0, 0, 5};
  c.look_at = {0, 0, 0};
  c.up = {0, 1e-13f, 0};  // short, but its direction is plain
  EXPECT_EQ(camera_problem(c), "");
  EXPECT_NO_THROW(CameraRays(c, 4, 4));
  c.up = {0, 0, 0};
  EXPECT_EQ(camera_problem(c), "up is zero");
  c.up = {0, 0, -3};
  EXPECT_EQ(camera_problem(c), "up is parallel to the view direction");
  // look_at - eye overflows float: fine in double.
  c.eye = {2e38f, 0, 0};
  c.look_at = {-2e38f, 0, 0};
  c.up = {0, 1, 0};
  EXPECT_EQ(camera_problem(c), "");
  EXPECT_NO_THROW(CameraRays(c, 4, 4));
  // An eye 1e-30 from look_at: its squared distance underflows float, not double.
  c.eye = {1e-30f, 0, 0};
  c.look_at = {0, 0, 0};
  EXPECT_EQ(camera_problem(c), "");
  c.look_at = c.eye;
  EXPECT_EQ(camera_problem(c), "eye and look_at coincide");
  c.eye = {std::numeric_limits<float>::infinity(), 0, 0};
  EXPECT_EQ(camera_problem(c), "eye, look_at and up must be finite");
  c.eye = {0, 0, 5};
  c.look_at = {0, 0, 0};
  c.vfov_deg = 0.0f;
  EXPECT_NE(camera_problem(c).find("vfov_deg must be in (0, 180)"), std::string::npos);
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
