// Logging: spdlog, one process-wide logger writing to stderr.
#pragma once

#include <spdlog/spdlog.h>

namespace rtc {

/// Sets up the process logger (stderr, "[time] [level] message"); level is one of
/// trace, debug, info, warn, error, off. Call once from main.
void init_logging(const std::string& level = "info");

}  // namespace rtc
