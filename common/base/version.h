// The build's identity, sent in worker hellos and logged by every program.
#pragma once

#include <string>

namespace rtc {

/// "rtc 0.1.0 (g++ 12.2.0, Release)": project version, compiler and build type. Peers with a
/// different build id may differ in pixels; the master logs a warning for them.
[[nodiscard]] std::string build_id();

}  // namespace rtc
