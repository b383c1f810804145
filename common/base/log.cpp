// Logging setup.
#include "common/base/log.h"

#include <spdlog/sinks/stdout_color_sinks.h>

namespace rtc {

void init_logging(const std::string& level) {
  auto logger = spdlog::stderr_color_mt("rtc");
  logger->set_pattern("[%H:%M:%S.%e] [%^%l%$] %v");
  logger->set_level(spdlog::level::from_str(level));
  spdlog::set_default_logger(logger);
}

}  // namespace rtc
