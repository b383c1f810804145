// Checks for command-line values that CLI11's own validators let through. Header-only; include
// it from mains and the *_cli.h option headers only (needs CLI11).
#pragma once

#include <cmath>
#include <cstdlib>
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

}  // namespace rtc
