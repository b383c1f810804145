// The body shared by the mesh and scene loader fuzz targets: load files written from the input
// and accept only success or an rtc::Error that names one of them; any other exception (or a
// crash, or a sanitizer report) is a finding.
#pragma once

#include <initializer_list>
#include <string>
#include <string_view>

#include "common/base/error.h"
#include "tests/fuzz/fuzz_support.h"

namespace rtc::fuzz {

/// Runs `load()`; an rtc::Error must name one of `files` (file names, as written to
/// scratch_dir()). Returns whether it loaded.
template <typename Load>
bool load_or_named_error(Load&& load, std::initializer_list<std::string_view> files) {
  try {
    load();
    return true;
  } catch (const rtc::Error& e) {
    const std::string message = e.what();
    for (std::string_view f : files) {
      if (message.find(f) != std::string::npos) return false;
    }
    fail("the error names none of the input files: " + message);
  }
}

}  // namespace rtc::fuzz
