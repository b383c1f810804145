// Checks for command-line values that CLI11's own validators let through, and the programs' one
// way of parsing a command line. Header-only; include it from mains and the *_cli.h option
// headers only (needs CLI11).
#pragma once

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>

namespace rtc {

/// Refuses "nan" (and "-nan", "NaN", ...) for a floating-point option. CLI::Range and
/// CLI::PositiveNumber compare the value with their bounds, and every comparison with NaN is
/// false, so NaN passed them: `--loop nan` ran for ever, `--min-weight nan` rendered.
/// Chain it before the range check: `->check(rtc::kNotNan)->check(CLI::Range(a, b))`.
inline const CLI::Validator kNotNan(
    [](std::string& text) {
      const double value = std::strtod(text.c_str(), nullptr);
      return std::isnan(value) ? "Value " + text + " is not a number" : std::string();
    },
    "", "NOT_NAN");

/// Refuses an empty value for an option whose absence means something else (`--isa ""` ran with
/// the default ISA and `--token-file ""` with no token, as if the option were not given).
inline const CLI::Validator kNotEmpty(
    [](std::string& text) { return text.empty() ? std::string("the value is empty") : std::string(); }, "",
    "NOT_EMPTY");

/// Parses the command line as CLI11_PARSE does, except that a usage error reads like rtc's other
/// errors: one "PROGRAM: error: MESSAGE" line and a pointer to --help on stderr, exit status 2
/// (CLI11's own codes, 105-109, came with no program name). --help prints the help on stdout
/// and gives 0. Returns the exit status where the program should stop, nothing where it goes on.
inline std::optional<int> parse_command_line(CLI::App& app, int argc, const char* const* argv, const char* program) {
  try {
    app.parse(argc, argv);
    return std::nullopt;
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) return app.exit(e);  // --help
    std::fprintf(stderr, "%s: error: %s\nrun '%s --help' for the options\n", program, e.what(), program);
    return 2;
  }
}

}  // namespace rtc
