// No NaN or infinity ever reaches a pixel: the default scene and shared scenes rendered with
// reflection depths 0..64 and no weight cut-off, at every ISA, in packets and single rays,
// every channel scanned (RGBA, depth, normal). Also scenes scaled to the edges of float.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <initializer_list>
#include <string>

#include "common/base/error.h"
#include "common/image/image.h"
#include "common/render/renderer.h"
#include "common/scene/load.h"
#include "tests/stress/stress_support.h"
#include "tests/support/reference_render.h"

namespace rtc::stress {
namespace {

// Every channel: RGBA finite, alpha 1; depth positive and finite where a surface was hit and
// exactly +inf (the background value) where none was, with the normal zero exactly there;
// normals finite and of unit length elsewhere.
std::uint64_t scan(const Image& img, const std::string& what) {
  std::uint64_t bad = 0;
  auto fail = [&](int x, int y, const std::string& why) {
    if (bad++ < 5) ADD_FAILURE() << what << ": pixel (" << x << ", " << y << "): " << why;
  };
  for (int y = 0; y < img.height; ++y) {
    for (int x = 0; x < img.width; ++x) {
      const float* p = img.pixel(x, y);
      for (int c = 0; c < 4; ++c) {
        if (!std::isfinite(p[c])) fail(x, y, "channel " + std::to_string(c) + " = " + std::to_string(p[c]));
      }
      if (p[3] != 1.0f) fail(x, y, "alpha " + std::to_string(p[3]));
      const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(img.width) + static_cast<std::size_t>(x);
      const float z = img.depth.at(i);
      const glm::vec3 n(img.normal.at(3 * i), img.normal.at(3 * i + 1), img.normal.at(3 * i + 2));
      if (!std::isfinite(n.x) || !std::isfinite(n.y) || !std::isfinite(n.z)) {
        fail(x, y, "normal not finite");
      } else if (z == std::numeric_limits<float>::infinity()) {
        if (n != glm::vec3(0.0f)) fail(x, y, "background depth with a normal");
      } else if (!(z > 0.0f) || !std::isfinite(z)) {
        fail(x, y, "depth " + std::to_string(z));
      } else if (std::fabs(glm::length(n) - 1.0f) > 1e-3f) {
        fail(x, y, "normal of length " + std::to_string(glm::length(n)));
      }
    }
  }
  return bad;
}

// Renders `scene` with max depth 0, 1, 8 and 64 and min weight 0 at every ISA, packets and
// single rays; scans every image and requires them all equal per depth.
void render_everywhere(const Scene& scene, const std::string& name, std::initializer_list<int> depths = {0, 1, 8, 64}) {
  for (const int max_depth : depths) {
    RenderSettings settings = scene.settings;
    settings.max_depth = max_depth;
    settings.min_weight = 0.0f;
    // One tree for all variants: the state only carries settings besides the geometry.
    const auto fs = build_frame_state(scene, 0, settings, KdBuildOptions{});
    std::string reference;
    for (const Isa isa : available_isas()) {
      for (const bool packets : {true, false}) {
        RenderOptions o;
        o.isa = isa;
        o.packets = packets;
        o.settings = settings;
        const Renderer r(scene, o);
        const Image img = r.render_frame(*fs, 16);
        const std::string what = name + ", max depth " + std::to_string(max_depth) + ", " +
                                 std::string(isa_name(isa)) + (packets ? " packets" : " single rays");
        EXPECT_EQ(scan(img, what), 0u) << what;
        const std::string hash = image_hash(img);
        if (reference.empty()) reference = hash;
        EXPECT_EQ(hash, reference) << what << ": pixels differ from the first variant";
      }
    }
  }
  std::printf("%s: %dx%d, %llu triangles, %zu depths x %zu ISAs x packets/single scanned\n", name.c_str(),
              scene.width, scene.height, static_cast<unsigned long long>(scene.triangle_count()),
              depths.size(), available_isas().size());
}

TEST(StressNoNan, DefaultScene) {
  Scene s = default_scene();
  set_resolution(s, 96, 72);
  render_everywhere(s, "default scene");
}

TEST(StressNoNan, SharedScenes) {
  const std::filesystem::path root = RTC_SHARED_SCENES;
  if (!std::filesystem::is_directory(root)) GTEST_SKIP() << "shared scene pack not found at " << root;
  // Mirrors everywhere (teapot), a mirror floor with 5 lights (gears), a closed interior with
  // chrome and glass (office), the sphereflake (balls-s3), 11 K degenerate triangles (engine).
  for (const char* view : {"spd-teapot/view.json", "spd-gears/view.json", "radiance-office/view.json",
                           "spd-balls-s3/view.json", "gltf-samples/view.json"}) {
    if (!std::filesystem::exists(root / view)) {
      std::printf("%s: not in the scene pack, skipped\n", view);
      continue;
    }
    Scene s = load_scene(root / view);
    set_resolution(s, 64, 48);
    render_everywhere(s, view);
  }
}

// Every length of the default scene times `scale`, moved by `offset` (double, rounded once).
Scene scaled_default(double scale, const glm::dvec3& offset) {
  Scene s = default_scene();
  set_resolution(s, 48, 36);
  auto P = [&](const glm::vec3& p) { return glm::vec3(glm::dvec3(p) * scale + offset); };
  for (Mesh& m : s.meshes) {
    const glm::dmat4 world(m.world_from_object);
    for (glm::vec3& p : m.positions) p = P(glm::vec3(world * glm::dvec4(glm::dvec3(p), 1.0)));
    m.world_from_object = glm::mat4(1.0f);
  }
  s.animation.meshes.clear();
  s.animation.camera.clear();
  s.animation.lights.clear();
  for (PointLight& l : s.lights) l.position = P(l.position);
  s.camera.eye = P(s.camera.eye);
  s.camera.look_at = P(s.camera.look_at);
  return s;
}

TEST(StressNoNan, ScenesAtTheEdgesOfFloat) {
  // Coordinates from 1e-30 to 1e30: squared lengths underflow to 0 or overflow to inf in float
  // (normals, light directions), exactly where a NaN would be born. Every length scaled alike,
  // the picture must stay the picture at scale 1: a normal or light direction lost to an
  // overflow or underflow shows as a wrongly lit surface, not as a NaN.
  const Scene unit_scene = scaled_default(1.0, glm::dvec3(0.0));
  const Image unit_image = Renderer(unit_scene).render_frame(*build_frame_state(unit_scene, 0, unit_scene.settings, KdBuildOptions{}), 16);
  for (const double scale : {1e-30, 1e-20, 1e18, 1e30}) {  // 1e-4..1e6: self_intersection_test
    const std::string name = "default scene x " + std::to_string(scale);
    Scene s;
    try {
      s = scaled_default(scale, glm::dvec3(0.0));
      (void)Renderer(s);
    } catch (const Error& e) {
      // Refusing such a scene with a message is allowed; rendering NaN is not.
      std::printf("%s: refused: %s\n", name.c_str(), e.what());
      continue;
    }
    render_everywhere(s, name, {1, 64});
    const Image img = Renderer(s).render_frame(*build_frame_state(s, 0, s.settings, KdBuildOptions{}), 16);
    const test::ImageError e = test::image_error(img, unit_image);
    std::printf("%s against scale 1: RMSE %.3e, max %.4f, %.2f%% of pixels over 1/255\n", name.c_str(), e.rmse,
                e.max_abs, e.pct_over_1_255);
    EXPECT_LE(e.pct_over_1_255, 1.0) << name;
  }
}

}  // namespace
}  // namespace rtc::stress
