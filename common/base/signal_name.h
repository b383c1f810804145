// A signal's name as logs and messages spell it.
#pragma once

#include <cstring>
#include <string>

namespace rtc {

/// "SIGINT", "SIGTERM", "SIGHUP", ... (glibc's sigabbrev_np with "SIG" before it), or "signal N"
/// for a number without a name. Not async-signal-safe (it builds a string): for messages written
/// after a handler has returned, not from one.
[[nodiscard]] inline std::string signal_name(int signo) {
  if (const char* abbrev = ::sigabbrev_np(signo); abbrev != nullptr) return std::string("SIG") + abbrev;
  return "signal " + std::to_string(signo);
}

}  // namespace rtc
