// The double-precision reference (tests/support/reference_render.h) is only worth measuring
// against if it is right: its visibility is cross-checked with Embree on the shared views, its
// watertight test is checked on shared edges and vertices, and its image is checked against
// rtc's renderer where both must agree.
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "common/base/error.h"
#include "common/math/ray_offset.h"
#include "common/render/renderer.h"
#include "common/scene/load.h"
#include "common/scene/mesh_builder.h"
#include "common/scene/tessellate.h"
#include "tests/support/embree_oracle.h"
#include "tests/support/hit_compare.h"
#include "tests/support/reference_render.h"

namespace rtc {
namespace {

RayHit to_float(const test::RefHit& h, float t_max) {
  if (h.prim == kNoHit) return RayHit{t_max, 0.0f, 0.0f, kNoHit};
  return RayHit{static_cast<float>(h.t), static_cast<float>(h.beta), static_cast<float>(h.gamma), h.prim};
}

class ReferenceView : public ::testing::TestWithParam<const char*> {};

// Primary visibility on the view's own camera rays against Embree (robust mode): they may
// differ only at edges and in verified ties; shadow rays from the reference's hits to every
// light agree on occlusion for all but a few grazing rays.
TEST_P(ReferenceView, AgreesWithEmbree) {
  const std::filesystem::path view = std::filesystem::path(RTC_SHARED_SCENES) / GetParam() / "view.json";
  if (!std::filesystem::exists(view)) GTEST_SKIP() << view << " is absent (the shared scene pack is not here)";
  Scene scene = load_scene(view);
  set_resolution(scene, 256, 256);
  const auto fs = build_frame_state(scene, scene.animation.frame_begin, scene.settings, KdBuildOptions{});
  const test::ReferenceTracer ref(fs->geometry->positions, fs->geometry->triangles);
  const std::vector<RayQuery> rays = test::pixel_centre_rays(fs->camera_rays);
  std::vector<RayHit> ours(rays.size()), theirs(rays.size());
  for (std::size_t i = 0; i < rays.size(); ++i) {
    ours[i] = to_float(ref.intersect(glm::dvec3(rays[i].org), glm::dvec3(rays[i].dir), 0.0, INFINITY), rays[i].t_max);
  }
  const test::EmbreeScene embree(fs->geometry->positions, fs->geometry->triangles, true);
  embree.intersect(rays.data(), theirs.data(), rays.size(), test::EmbreeMode::Single);
  const test::HitComparison c = test::compare_hits(fs->geometry->positions, fs->geometry->triangles, rays, ours, theirs);
  std::printf("%s: reference vs Embree: %s\n", GetParam(), c.summary().c_str());
  EXPECT_EQ(c.bad_ties + c.same_prim_t_bad, 0u) << c.summary();
  EXPECT_EQ(c.hit_miss_disagree, c.hit_miss_on_edge) << c.summary();
  EXPECT_GE(c.hit_miss_agreement(), 0.9999) << c.summary();

  // Shadow rays: from each reference hit point (float, offset like the renderer's) to each light.
  std::vector<RayQuery> shadow;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    if (ours[i].prim == kNoHit) continue;
    const glm::uvec3 tri = fs->geometry->triangles[ours[i].prim];
    const glm::vec3 a = fs->geometry->positions[tri.x], b = fs->geometry->positions[tri.y], cc = fs->geometry->positions[tri.z];
    glm::vec3 n = glm::normalize(glm::cross(b - a, cc - a));
    if (glm::dot(n, rays[i].dir) > 0.0f) n = -n;
    const glm::vec3 p = a * (1.0f - ours[i].beta - ours[i].gamma) + b * ours[i].beta + cc * ours[i].gamma;
    const glm::vec3 o = offset_ray_origin(p, n, vertex_magnitude(a, b, cc));  // the renderer's offset
    for (const PointLight& l : fs->lights) shadow.push_back(RayQuery{o, 0.0f, l.position - o, 1.0f});
  }
  std::vector<std::uint8_t> occ(shadow.size());
  embree.occluded(shadow.data(), occ.data(), shadow.size(), test::EmbreeMode::Single);
  std::size_t differ = 0;
  for (std::size_t i = 0; i < shadow.size(); ++i) {
    const bool r = ref.occluded(glm::dvec3(shadow[i].org), glm::dvec3(shadow[i].dir), 0.0, 1.0);
    differ += r != (occ[i] != 0) ? 1 : 0;
  }
  const double frac = shadow.empty() ? 0.0 : static_cast<double>(differ) / static_cast<double>(shadow.size());
  std::printf("%s: %zu shadow rays, occlusion differs on %zu (%.5f%%)\n", GetParam(), shadow.size(), differ, 100.0 * frac);
  EXPECT_LE(frac, 1e-4) << differ << " of " << shadow.size() << " shadow rays differ";
}

INSTANTIATE_TEST_SUITE_P(Shared, ReferenceView,
                         ::testing::Values("bunny", "spd-teapot", "radiance-office", "spd-balls-s3", "spd-gears"),
                         [](const ::testing::TestParamInfo<const char*>& param) {
                           std::string s = param.param;
                           for (char& ch : s) ch = std::isalnum(static_cast<unsigned char>(ch)) ? ch : '_';
                           return s;
                         });

// The watertight double test: rays aimed exactly at the shared vertices and edge midpoints
// (exact in double) of closed cube-spheres, from outside and at least 30 degrees off the
// tangent plane (a ray aimed at a point of the silhouette may rightly pass outside), at several
// scales: all hit.
TEST(ReferenceTracer, NoRaySlipsThroughSharedEdgesOrVertices) {
  const SphereTemplate unit = make_cube_sphere(12);
  for (const double scale : {1e-3, 1.0, 1e4}) {
    const glm::dvec3 center = glm::dvec3(0.3, -0.2, 0.1) * scale;
    std::vector<glm::vec3> pos;
    for (const glm::dvec3& p : unit.points) pos.push_back(glm::vec3(p * scale + center));
    const test::ReferenceTracer ref(pos, unit.triangles);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::size_t rays = 0, misses = 0;
    for (const glm::uvec3& t : unit.triangles) {
      const glm::dvec3 a(pos[t.x]), b(pos[t.y]), c(pos[t.z]);
      const glm::dvec3 targets[4] = {a, (a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5};
      for (const glm::dvec3& target : targets) {
        const glm::dvec3 n = glm::normalize(target - center);
        glm::dvec3 side(u(rng), u(rng), u(rng));
        side -= n * glm::dot(side, n);  // tangential, length <= sqrt(3) * ... scaled below
        const double len = glm::length(side);
        if (len > 0.0) side *= 0.8 / len * std::abs(u(rng));  // at most ~39 degrees off the normal
        const glm::dvec3 o = target + glm::normalize(n + side) * (2.0 * scale);
        const glm::dvec3 d = target - o;
        ++rays;
        if (ref.intersect(o, d, 0.0, 2.0).prim == kNoHit) {
          ++misses;
          ADD_FAILURE() << "scale " << scale << ": ray from (" << o.x << ", " << o.y << ", " << o.z << ") to ("
                        << target.x << ", " << target.y << ", " << target.z << ") slipped through";
          if (misses > 5) return;
        }
      }
    }
    std::printf("scale %g: %zu rays at shared edges/vertices, %zu missed\n", scale, rays, misses);
  }
}

// On a scene where float and double must agree to well within a display step (the default
// scene: large spheres and planes, no grazing geometry), rtc's render with the reference's
// settings (depth 64, no cutoff) is within 1/255 on at least 99.9% of pixels.
TEST(ReferenceRender, MatchesTheRendererOnTheDefaultScene) {
  Scene scene = default_scene();
  set_resolution(scene, 160, 120);
  scene.settings.max_depth = 64;
  scene.settings.min_weight = 0.0f;
  Renderer renderer(scene);
  const auto state = renderer.prepare(scene.animation.frame_begin);
  const Image ours = renderer.render_frame(*state);
  const test::ReferenceTracer ref(state->geometry->positions, state->geometry->triangles);
  const Image reference = test::reference_render(*state, ref);
  const test::ImageError e = test::image_error(ours, reference);
  std::printf("default scene: RMSE %.3e, max %.4f, %.4f%% of pixels over 1/255\n", e.rmse, e.max_abs, e.pct_over_1_255);
  EXPECT_EQ(e.non_finite, 0u);
  EXPECT_EQ(test::count_non_finite(reference), 0u);
  EXPECT_LE(e.pct_over_1_255, 0.1);
}

TEST(ReferenceRender, FarLightsLightAsTheyShould) {
  // A light 1e20 away, the usual stand-in for a directional light: the direction to it has a
  // squared length beyond the float range, and the renderer must still light by its direction.
  Scene scene = default_scene();
  set_resolution(scene, 96, 72);
  for (PointLight& l : scene.lights) l.position *= 1e20f;
  Renderer renderer(scene);
  const auto state = renderer.prepare(scene.animation.frame_begin);
  const Image ours = renderer.render_frame(*state);
  const test::ReferenceTracer ref(state->geometry->positions, state->geometry->triangles);
  const Image reference = test::reference_render(*state, ref, test::ReferenceOptions{scene.settings.max_depth, scene.settings.min_weight});
  const test::ImageError e = test::image_error(ours, reference);
  std::printf("default scene, lights 1e20 out: RMSE %.3e, max %.4f, %.4f%% of pixels over 1/255\n", e.rmse, e.max_abs,
              e.pct_over_1_255);
  EXPECT_EQ(e.non_finite, 0u);
  EXPECT_LE(e.pct_over_1_255, 0.5);
}

TEST(ImageError, MeasuresDisplayDifferences) {
  Image a(2, 1), b(2, 1);
  for (int x = 0; x < 2; ++x) {
    for (int c = 0; c < 3; ++c) a.pixel(x, 0)[c] = b.pixel(x, 0)[c] = 0.5f;
  }
  EXPECT_EQ(test::image_error(a, b).rmse, 0.0);
  EXPECT_TRUE(std::isinf(test::image_error(a, b).psnr_db));
  b.pixel(1, 0)[0] = 1.0f;  // sRGB(0.5) = 0.7354, sRGB(1) = 1
  const test::ImageError e = test::image_error(a, b);
  EXPECT_NEAR(e.max_abs, 1.0 - 0.735356983, 1e-6);
  EXPECT_DOUBLE_EQ(e.pct_over_1_255, 50.0);
  EXPECT_NEAR(e.rmse, std::sqrt((1.0 - 0.735356983) * (1.0 - 0.735356983) / 6.0), 1e-6);
  a.pixel(0, 0)[1] = std::nanf("");
  EXPECT_EQ(test::image_error(a, b).non_finite, 1u);
  EXPECT_THROW((void)test::image_error(a, Image(3, 1)), Error);
}

}  // namespace
}  // namespace rtc
