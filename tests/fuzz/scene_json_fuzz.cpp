// Fuzz target: the scene JSON parser (docs/scene-format.md; common/scene/scene_json.cpp) through
// load_scene, as rtc-render and rtc-master load a scene. The scratch folder holds a small mesh
// "cube.obj" the JSON may name, so inputs get past the mesh loading into cameras, lights,
// materials, animation tracks and render settings.
#include <string_view>

#include "common/scene/load.h"
#include "tests/fuzz/fuzz_support.h"
#include "tests/fuzz/loader_fuzz.h"

namespace {

constexpr std::string_view kCube =
    "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n"
    "f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 4 7 3\nf 4 8 7\nf 1 5 8\nf 1 8 4\n"
    "f 2 3 7\nf 2 7 6\n";

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const bool cube_written = (rtc::fuzz::write_file("cube.obj", kCube), true);
  (void)cube_written;
  const auto path = rtc::fuzz::write_file("scene.json", rtc::fuzz::as_text(data, size));
  rtc::fuzz::load_or_named_error([&] { (void)rtc::load_scene(path); }, {"scene.json", "cube.obj"});
  return 0;
}
