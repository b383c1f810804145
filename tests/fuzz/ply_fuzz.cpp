// Fuzz target: the PLY loader (ascii, binary little and big endian; common/scene/ply_loader.cpp).
#include "common/scene/mesh_file.h"
#include "tests/fuzz/fuzz_support.h"
#include "tests/fuzz/loader_fuzz.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = rtc::fuzz::write_file("m.ply", rtc::fuzz::as_text(data, size));
  rtc::fuzz::load_or_named_error([&] { (void)rtc::load_mesh_file(path); }, {"m.ply"});
  return 0;
}
