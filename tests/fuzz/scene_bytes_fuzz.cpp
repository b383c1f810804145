// Fuzz target: scenes as bytes from the wire (common/scene/serialize.h), what a worker decodes
// from the master's SceneChunks. Bad bytes must give rtc::Error naming the source; a scene that
// decodes must serialize to bytes that decode to the same scene.
#include <span>
#include <string>

#include "common/base/error.h"
#include "common/scene/serialize.h"
#include "tests/fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using rtc::fuzz::check;
  const std::string what = "fuzzed scene bytes";
  rtc::Scene scene;
  try {
    scene = rtc::deserialize_scene(std::span<const std::uint8_t>(data, size), what);
  } catch (const rtc::Error& e) {
    check(std::string(e.what()).find(what) != std::string::npos,
          std::string("the error does not name the source: ") + e.what());
    return 0;
  }
  const std::vector<std::uint8_t> bytes = rtc::serialize_scene(scene);
  rtc::Scene again;
  try {
    again = rtc::deserialize_scene(bytes, "re-serialized scene");
  } catch (const rtc::Error& e) {
    rtc::fuzz::fail(std::string("a decoded scene does not decode once serialized: ") + e.what());
  }
  check(rtc::serialize_scene(again) == bytes, "serialize(deserialize(serialize(s))) differs from serialize(s)");
  return 0;
}
