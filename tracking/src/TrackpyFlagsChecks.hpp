// Checks of the values given to command-line flags (`mmval track` and `mmval synth`):
// a bad value stops with an InputError (exit 2) that names the flag, the value as
// given and what the flag expects.
#pragma once
#include <cmath>
#include <cstdint>
#include <exception>
#include <string>

#include <fmt/format.h>

#include "mmval/core/Error.hpp"

namespace mmval::tracking::detail {

/// A number given as text to `flag`, finite and in [lo, hi]; InputError naming the flag and
/// `expected` otherwise (trailing text such as "2x" is refused).
inline double flagNumber(const char* flag, const std::string& text, double lo, double hi, const std::string& expected) {
  double v = 0;
  std::size_t used = 0;
  try {
    v = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != text.size() || !std::isfinite(v) || v < lo || v > hi)
    throw InputError({}, fmt::format("option {} has an invalid value", flag), fmt::format("{} {}", flag, text), expected);
  return v;
}

/// Whole-number flags: as flagNumber, and no fraction.
inline std::int64_t flagInteger(const char* flag, const std::string& text, std::int64_t lo, std::int64_t hi, const std::string& expected) {
  const double v = flagNumber(flag, text, static_cast<double>(lo), static_cast<double>(hi), expected);
  if (v != std::floor(v)) throw InputError({}, fmt::format("option {} has an invalid value", flag), fmt::format("{} {}", flag, text), expected);
  return static_cast<std::int64_t>(v);
}

/// A real value already parsed from `option` must be finite and in (lo, hi] (lo_open) or [lo, hi]: NaN and
/// infinities pass CLI11's own range checks (every comparison with NaN is false), and a bad
/// value must not be mistaken for a missing one.
inline void requireOptionValue(const char* option, double value, double lo, bool lo_open, double hi, const std::string& expected) {
  const bool ok = std::isfinite(value) && (lo_open ? value > lo : value >= lo) && value <= hi;
  if (!ok) throw InputError({}, fmt::format("option {} has an invalid value", option), fmt::format("{} {:g}", option, value), expected);
}

}  // namespace mmval::tracking::detail
