// Fuzz target: the NFF loader (Haines SPD; common/scene/nff_loader.cpp) with a coarse
// tessellation, so that each sphere or cone costs little and the run explores the parser.
#include "common/scene/mesh_file.h"
#include "tests/fuzz/fuzz_support.h"
#include "tests/fuzz/loader_fuzz.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = rtc::fuzz::write_file("m.nff", rtc::fuzz::as_text(data, size));
  rtc::MeshLoadOptions options;
  options.tessellation.sphere_quads = 1;
  options.tessellation.cone_segments = 3;
  rtc::fuzz::load_or_named_error([&] { (void)rtc::load_mesh_file(path, options); }, {"m.nff"});
  return 0;
}
