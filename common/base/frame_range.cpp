// Frame ranges on command lines (see frame_range.h).
#include "common/base/frame_range.h"

#include <algorithm>
#include <cctype>
#include <stdexcept>
#include <string>

#include "common/base/error.h"

namespace rtc {

FrameRange parse_frame_range(const std::string& text, const std::string& option) {
  FrameRange r;
  try {
    // std::stoi skips leading white space: " 1" was taken, "1 " refused.
    if (std::any_of(text.begin(), text.end(), [](unsigned char c) { return std::isspace(c) != 0; })) {
      throw std::invalid_argument(text);
    }
    const std::size_t dash = text.find('-', 1);
    std::size_t used = 0;
    r.first = std::stoi(text.substr(0, dash), &used);
    if (used != (dash == std::string::npos ? text.size() : dash)) throw std::invalid_argument(text);
    r.last = r.first;
    if (dash != std::string::npos) {
      r.last = std::stoi(text.substr(dash + 1), &used);
      if (used != text.size() - dash - 1) throw std::invalid_argument(text);
    }
  } catch (const std::out_of_range&) {
    throw Error(option + ": " + text + ": frame numbers must be at most " + std::to_string(kMaxFrameNumber));
  } catch (const std::exception&) {
    throw Error(option + ": expected A-B or A, got \"" + text + "\"");
  }
  if (r.first < 0 || r.last < 0) throw Error(option + ": " + text + ": frame numbers must be >= 0");
  if (r.last < r.first) throw Error(option + ": " + text + " is an empty range");
  if (r.last > kMaxFrameNumber) {
    throw Error(option + ": " + text + ": frame numbers must be at most " + std::to_string(kMaxFrameNumber));
  }
  return r;
}

}  // namespace rtc
