// FrustumCull: every ray of a rectangle it culls fails the kd-tree traversal's own float slab
// test against the box, for boxes in front of, beside and around the eye; and it culls a fair
// share of what it could.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <random>

#include "common/math/frustum_cull.h"

namespace rtc {
namespace {

// The traversal's entry test (common/accel/kd_traverse.h, traverse_coherent) in float, with
// the watertight traversal's looser reach: true when the ray's segment in the box is not empty.
bool slab_enters(const Ray& r, const Aabb& box) {
  float near = 0.0f, far = std::numeric_limits<float>::infinity();
  for (int a = 0; a < 3; ++a) {
    const float inv = 1.0f / r.dir[a];
    const bool neg = std::signbit(r.dir[a]);
    const float t_entry = ((neg ? box.hi[a] : box.lo[a]) - r.origin[a]) * inv;
    const float t_exit = ((neg ? box.lo[a] : box.hi[a]) - r.origin[a]) * inv;
    near = t_entry > near ? t_entry : near;  // NaN keeps near, as the SIMD max does
    far = t_exit < far ? t_exit : far;
  }
  return near <= far * (1.0f + 0x1p-20f);
}

struct Case {
  Camera camera;
  Aabb box;
  int width, height;
};

Case random_case(std::mt19937& rng, float spread) {
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::uniform_real_distribution<float> size(0.01f, 3.0f);
  std::uniform_real_distribution<float> fov(10.0f, 120.0f);
  Case c;
  const glm::vec3 center(u(rng), u(rng), u(rng));
  const glm::vec3 half(size(rng), size(rng), size(rng));
  c.box.lo = center - half;
  c.box.hi = center + half;
  // Eyes near the box (corners behind the eye: the clipped test) and far (the projected
  // rectangle), looking at the box, beside it or away.
  const float distance = std::uniform_real_distribution<float>(0.5f, 30.0f)(rng);
  c.camera.eye = center + glm::normalize(glm::vec3(u(rng), u(rng), u(rng))) * distance;
  c.camera.look_at = center + glm::vec3(u(rng), u(rng), u(rng)) * (spread * (1.0f + distance));
  c.camera.up = glm::vec3(u(rng), u(rng), u(rng));
  c.camera.vfov_deg = fov(rng);
  c.width = 48;
  c.height = 36;
  return c;
}

TEST(FrustumCull, CulledRaysNeverEnterTheBox) {
  std::mt19937 rng(20240611);
  int culled_pixels = 0, missing_pixels = 0, cases = 0;
  for (int n = 0; n < 400; ++n) {
    const Case c = random_case(rng, n % 2 == 0 ? 0.5f : 4.0f);
    std::optional<CameraRays> made;
    try {
      made.emplace(c.camera, c.width, c.height);
    } catch (const std::exception&) {
      continue;  // up parallel to the view
    }
    const CameraRays& rays = *made;
    ++cases;
    const FrustumCull cull(rays, c.box);
    const double subs[] = {0.0, 0.5, 0.99999994};
    for (int y = 0; y < c.height; ++y) {
      for (int x = 0; x < c.width; ++x) {
        const bool culled = cull.misses(x, y, x + 1, y + 1);
        bool enters = false;
        for (double sx : subs) {
          for (double sy : subs) {
            const Ray r = rays.ray(x, y, sx, sy);
            if (slab_enters(r, c.box)) {
              enters = true;
              if (culled) {
                ADD_FAILURE() << "case " << n << " pixel " << x << "," << y << ": ray " << std::hexfloat << r.origin.x
                              << " " << r.origin.y << " " << r.origin.z << " dir " << r.dir.x << " " << r.dir.y << " "
                              << r.dir.z << " enters the box but was culled";
              }
            }
          }
        }
        culled_pixels += culled ? 1 : 0;
        missing_pixels += enters ? 0 : 1;
      }
    }
    // A culled rectangle's sub-rectangles are culled too (the tile test and the packet test agree).
    if (cull.misses(0, 0, c.width, c.height)) {
      EXPECT_TRUE(cull.misses(0, 0, c.width / 2, c.height / 2)) << "case " << n;
    }
  }
  std::printf("%d cases: %d of %d pixels whose 9 rays miss the box were culled\n", cases, culled_pixels, missing_pixels);
  EXPECT_GT(cases, 300);
  EXPECT_GT(culled_pixels, missing_pixels / 2) << "the test culls too little to be of use";
}

// The ray at real image position (px, py).
Ray ray_at(const CameraRays& rays, double px, double py) {
  const double fx = std::floor(px), fy = std::floor(py);
  return rays.ray(static_cast<int>(fx), static_cast<int>(fy), px - fx, py - fy);
}

// Right at the silhouette of the box, where the float rays' rounding decides: along rows, the
// position where the rays stop entering the box is found by bisection, and no point near it
// (1e-9 to 1e-2 pixels to either side) whose ray enters may be culled.
TEST(FrustumCull, CullsNoRayThatEntersAtTheBoxEdge) {
  std::mt19937 rng(77);
  int edges = 0;
  for (int n = 0; n < 300; ++n) {
    const Case c = random_case(rng, 0.3f);
    std::optional<CameraRays> made;
    try {
      made.emplace(c.camera, c.width, c.height);
    } catch (const std::exception&) {
      continue;
    }
    const CameraRays& rays = *made;
    const FrustumCull cull(rays, c.box);
    for (int y = 0; y < c.height; y += 5) {
      const double py = y + 0.5;
      for (int x = 0; x + 1 < c.width; ++x) {
        double in = x + 0.5, out = x + 1.5;
        const bool enters_a = slab_enters(ray_at(rays, in, py), c.box);
        if (enters_a == slab_enters(ray_at(rays, out, py), c.box)) continue;
        if (!enters_a) std::swap(in, out);
        for (int i = 0; i < 60; ++i) {
          const double mid = 0.5 * (in + out);
          (slab_enters(ray_at(rays, mid, py), c.box) ? in : out) = mid;
        }
        ++edges;
        const double step = out > in ? 1.0 : -1.0;
        for (double d = 1e-9; d < 2e-2; d *= 3.0) {
          for (const double p : {in - step * d, in, out, out + step * d}) {
            if (cull.misses(p, py, p, py) && slab_enters(ray_at(rays, p, py), c.box)) {
              ADD_FAILURE() << "case " << n << ": position " << p << ", " << py << " (" << d
                            << " px from the edge) was culled, but its ray enters the box";
            }
          }
        }
      }
    }
  }
  std::printf("%d silhouette crossings tried\n", edges);
  EXPECT_GT(edges, 500);
}

TEST(FrustumCull, EmptyBoxCullsEverythingAndTheEyeInsideNothing) {
  const CameraRays rays(Camera{}, 32, 32);
  const FrustumCull empty(rays, Aabb{});
  EXPECT_TRUE(empty.active());
  EXPECT_TRUE(empty.misses(0, 0, 32, 32));
  Aabb around;
  around.extend(glm::vec3(-1.0f, -1.0f, 0.0f));
  around.extend(glm::vec3(1.0f, 1.0f, 2.0f));  // the default camera's eye is (0, 0, 1)
  const FrustumCull inside(rays, around);
  EXPECT_FALSE(inside.active());
  EXPECT_FALSE(inside.misses(0, 0, 1, 1));
  Aabb huge = around;
  huge.hi.x = std::numeric_limits<float>::infinity();
  EXPECT_FALSE(FrustumCull(rays, huge).active());
  EXPECT_FALSE(FrustumCull().active());
}

TEST(FrustumCull, BoxBehindTheEyeCullsEverything) {
  const CameraRays rays(Camera{}, 32, 32);  // eye (0, 0, 1) looking down -z
  Aabb behind;
  behind.extend(glm::vec3(-5.0f, -5.0f, 2.0f));
  behind.extend(glm::vec3(5.0f, 5.0f, 3.0f));
  EXPECT_TRUE(FrustumCull(rays, behind).misses(0, 0, 32, 32));
  // Reaching past the eye's plane: the part in front of the eye decides.
  Aabb beside = behind;
  beside.lo = glm::vec3(0.3f, -5.0f, -3.0f);
  const FrustumCull cull(rays, beside);
  EXPECT_TRUE(cull.misses(0, 0, 16, 32)) << "the left half looks away from the box";
  EXPECT_FALSE(cull.misses(16, 0, 32, 32));
}

}  // namespace
}  // namespace rtc
