// Errors for bad input: every message names the place (file and line, JSON field, peer).
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>

namespace rtc {

/// Thrown for bad input (scene files, meshes, messages, command lines). The message names
/// the place and the reason; `main` prints it and exits non-zero, library code never exits.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
  // Out of line (error.cpp): the class's vtable, type info and destructor then live in rtc_base
  // alone. Inline, every object file that throws one defined them, and the linker could take
  // them from any member of a static library, dragging that member's own dependencies (such as
  // OpenImageIO's 260 libraries) into programs that never use them.
  ~Error() override;
  Error(const Error&) = default;
  Error& operator=(const Error&) = default;
};

/// "file:line: message" (line 0 leaves the line out).
[[nodiscard]] std::string at_location(std::string_view file, std::uint64_t line, std::string_view message);

/// Throws rtc::Error("file:line: message").
[[noreturn]] void throw_at(std::string_view file, std::uint64_t line, std::string_view message);

/// Why nothing usable is at `path`: empty when something is there (a file, a folder, ...),
/// "file not found" when nothing is, else the system's reason ("Too many levels of symbolic
/// links" for a link loop, "Permission denied" for a folder on the way that cannot be searched).
[[nodiscard]] std::string missing_file_reason(const std::string& path);
/// missing_file_reason's answer when nothing is at the path.
inline constexpr std::string_view kFileNotFound = "file not found";

namespace detail {
[[noreturn]] void check_failed(const char* expr, const char* file, int line, const char* message);
}  // namespace detail

}  // namespace rtc

/// Guards our own invariants (never untrusted bytes); aborts with a message when false.
#define RTC_CHECK(cond, msg)                                                      \
  do {                                                                            \
    if (!(cond)) ::rtc::detail::check_failed(#cond, __FILE__, __LINE__, (msg));   \
  } while (0)

#ifdef NDEBUG
#define RTC_DCHECK(cond, msg) \
  do {                        \
  } while (0)
#else
#define RTC_DCHECK(cond, msg) RTC_CHECK(cond, msg)
#endif
