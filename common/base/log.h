// Logging: spdlog, one process-wide logger writing to stderr.
#pragma once

#include <spdlog/spdlog.h>

namespace rtc {

/// Sets up the process logger (stderr, "[time] [level] message"); level is one of
/// trace, debug, info, warn, error, critical, off (and spdlog's "warning", "err"); any other
/// word throws rtc::Error. Call once from main.
void init_logging(const std::string& level = "info");

}  // namespace rtc
