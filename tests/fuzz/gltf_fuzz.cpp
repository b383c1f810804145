// Fuzz target: the glTF 2.0 loader (through Assimp; common/scene/gltf_loader.cpp): a .glb when
// the input starts with the binary magic "glTF", else a .gltf (JSON with data: URI buffers).
#include <string_view>

#include "common/scene/mesh_file.h"
#include "tests/fuzz/fuzz_support.h"
#include "tests/fuzz/loader_fuzz.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text = rtc::fuzz::as_text(data, size);
  const std::string_view name = text.substr(0, 4) == "glTF" ? "m.glb" : "m.gltf";
  const auto path = rtc::fuzz::write_file(name, text);
  rtc::fuzz::load_or_named_error([&] { (void)rtc::load_mesh_file(path); }, {name});
  return 0;
}
