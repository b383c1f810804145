// Logging: spdlog, one process-wide logger writing to stderr.
#pragma once

#include <string>
#include <string_view>

#include <spdlog/spdlog.h>

namespace rtc {

/// Sets up the process logger (stderr, "[time] [level] message"); level is one of
/// trace, debug, info, warn, error, critical, off (and spdlog's "warning", "err"); any other
/// word throws rtc::Error. Call once from main.
void init_logging(const std::string& level = "info");

/// `text` from a peer (a worker's name, an error's text) as one log line's worth: control
/// characters as \n, \r, \t or \xNN, so that it cannot start a forged line or move the
/// terminal's cursor. Other bytes (UTF-8 too) are kept.
[[nodiscard]] std::string printable(std::string_view text);

/// "1 mesh", "3 meshes": a count with the noun in its number, for log lines.
[[nodiscard]] inline std::string counted(unsigned long long n, std::string_view one, std::string_view many) {
  return std::to_string(n) + ' ' + std::string(n == 1 ? one : many);
}

}  // namespace rtc
