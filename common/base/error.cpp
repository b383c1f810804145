// Error helpers: location-prefixed messages and the invariant-check failure path.
#include "common/base/error.h"

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <system_error>

namespace rtc {

Error::~Error() = default;

std::string at_location(std::string_view file, std::uint64_t line, std::string_view message) {
  std::string out(file);
  if (line > 0) {
    out += ':';
    out += std::to_string(line);
  }
  out += ": ";
  out += message;
  return out;
}

void throw_at(std::string_view file, std::uint64_t line, std::string_view message) {
  throw Error(at_location(file, line, message));
}

std::string missing_file_reason(const std::string& path) {
  std::error_code ec;
  const std::filesystem::file_status st = std::filesystem::status(path, ec);
  if (std::filesystem::exists(st)) return {};
  if (!ec || ec == std::errc::no_such_file_or_directory || ec == std::errc::not_a_directory) return std::string(kFileNotFound);
  return ec.message();
}

namespace detail {
void check_failed(const char* expr, const char* file, int line, const char* message) {
  std::fprintf(stderr, "rtc: internal check failed at %s:%d: %s (%s)\n", file, line, message, expr);
  std::abort();
}
}  // namespace detail

}  // namespace rtc
