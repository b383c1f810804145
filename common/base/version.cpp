// The build's identity (see version.h).
#include "common/base/version.h"

namespace rtc {

std::string build_id() {
#if defined(__clang__)
  const std::string compiler = "clang++ " __clang_version__;
#elif defined(__GNUC__)
  const std::string compiler = "g++ " __VERSION__;
#else
  const std::string compiler = "unknown compiler";
#endif
  return std::string("rtc ") + RTC_VERSION_STRING + " (" + compiler + ", " + RTC_BUILD_TYPE + ")";
}

}  // namespace rtc
