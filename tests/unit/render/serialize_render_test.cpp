// Scene bytes and pixels: a worker renders the scene it decoded from the master's bytes, so
// the round trip must not change a single pixel bit (image_hash) at any frame.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "common/image/image.h"
#include "common/render/renderer.h"
#include "common/scene/load.h"
#include "common/scene/serialize.h"

namespace rtc {
namespace {

std::string frame_hash(const Scene& scene, int frame) {
  Renderer renderer(scene);
  const auto state = renderer.prepare(frame);
  return image_hash(renderer.render_frame(*state, 16));
}

void expect_same_pixels_after_round_trip(const Scene& scene, const std::string& what) {
  const Scene copy = deserialize_scene(serialize_scene(scene), what);
  for (const int frame : {scene.animation.frame_begin, scene.animation.frame_end}) {
    EXPECT_EQ(frame_hash(copy, frame), frame_hash(scene, frame)) << what << ", frame " << frame;
  }
}

TEST(SceneBytesRender, DefaultSceneRendersTheSamePixelsAfterARoundTrip) {
  Scene scene = default_scene();
  scene.width = 80;
  scene.height = 60;
  scene.settings.spp = 2;
  expect_same_pixels_after_round_trip(scene, "default scene");
}

TEST(SceneBytesRender, SharedSceneRendersTheSamePixelsAfterARoundTrip) {
  const std::filesystem::path view =
      std::filesystem::path(RTC_SHARED_SCENES) / "spd-teapot/view.json";
  std::error_code ec;
  if (!std::filesystem::exists(view, ec)) GTEST_SKIP() << view << " not found; skipping";
  Scene scene = load_scene(view);
  set_resolution(scene, 64, 48);
  expect_same_pixels_after_round_trip(scene, view.string());
}

}  // namespace
}  // namespace rtc
