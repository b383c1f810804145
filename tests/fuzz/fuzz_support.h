// Shared by the fuzz targets (*_fuzz.cpp): a per-process scratch folder for loaders that read
// files, and checks that end the run with a message (a libFuzzer "crash") when a property fails.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string_view>

namespace rtc::fuzz {

/// A folder of this process's own (mkdtemp under $TMPDIR or /tmp), removed at exit.
[[nodiscard]] const std::filesystem::path& scratch_dir();

/// Writes `bytes` to scratch_dir() / name and returns the path.
std::filesystem::path write_file(std::string_view name, std::string_view bytes);

/// Prints "fuzz check failed: <what>" to stderr and aborts, so libFuzzer keeps the input.
[[noreturn]] void fail(std::string_view what);

/// fail(what) unless `ok`.
inline void check(bool ok, std::string_view what) {
  if (!ok) fail(what);
}

/// The input as text.
[[nodiscard]] inline std::string_view as_text(const std::uint8_t* data, std::size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

}  // namespace rtc::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size);
