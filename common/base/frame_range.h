// Frame ranges on command lines: "A-B" or "A", both inclusive.
#pragma once

#include <string>

namespace rtc {

struct FrameRange {
  int first = 0;
  int last = 0;
};

/// Parses "A-B" or "A" (frames >= 0, B >= A). Throws rtc::Error naming `option` and the text.
[[nodiscard]] FrameRange parse_frame_range(const std::string& text, const std::string& option = "--frames");

}  // namespace rtc
