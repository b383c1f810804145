// Frame ranges on command lines: "A-B" or "A", both inclusive.
#pragma once

#include <string>

namespace rtc {

struct FrameRange {
  int first = 0;
  int last = 0;
};

/// The largest frame number a command line takes (the scene format's limit too): loops to the
/// last frame then never overflow an int.
inline constexpr int kMaxFrameNumber = 1000000000;

/// Parses "A-B" or "A" (0 <= A <= B <= kMaxFrameNumber). Throws rtc::Error naming `option` and
/// the text.
[[nodiscard]] FrameRange parse_frame_range(const std::string& text, const std::string& option = "--frames");

}  // namespace rtc
