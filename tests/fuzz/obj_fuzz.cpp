// Fuzz target: the OBJ loader with its MTL library (common/scene/obj_loader.cpp). The input is
// an OBJ file, optionally followed by a line "#--mtl--" and the MTL file "m.mtl" it may name
// (mtllib m.mtl).
#include <string_view>

#include "common/scene/mesh_file.h"
#include "tests/fuzz/fuzz_support.h"
#include "tests/fuzz/loader_fuzz.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text = rtc::fuzz::as_text(data, size);
  constexpr std::string_view kSplit = "#--mtl--\n";
  const std::size_t split = text.find(kSplit);
  const auto obj = rtc::fuzz::write_file("m.obj", text.substr(0, split));
  rtc::fuzz::write_file("m.mtl", split == std::string_view::npos ? std::string_view() : text.substr(split + kSplit.size()));
  rtc::fuzz::load_or_named_error([&] { (void)rtc::load_mesh_file(obj); }, {"m.obj", "m.mtl"});
  return 0;
}
