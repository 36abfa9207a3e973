// Physical quantities with units at the boundaries, SI inside.
//
// A quantity string is a number followed by a unit expression:
//   "5 um", "0.024 cm/min", "5 uL/min", "2.5 D", "1.05 g/cm3", "20 min", "1e-3 Pa s".
// A unit expression is a product of unit symbols separated by spaces or '*',
// each with an optional integer exponent ("m2", "m^2", "s^-1"); a single '/'
// puts every following factor in the denominator ("kg/m3", "J/kg K").
// A bare number is taken as SI. Conversion factors: the darcy is
// 9.869233e-13 m^2 (API definition: 1 cP fluid, 1 cm/s through 1 cm^2 under
// 1 atm/cm), the poise 0.1 Pa s, the litre 1e-3 m^3.
#pragma once

#include <array>
#include <stdexcept>
#include <string>
#include <string_view>

namespace mmval {

/// Exponents of the SI base dimensions (length, mass, time, temperature,
/// amount) and of one non-SI base, computer memory in bytes (for limits such as
/// run.max_memory: "8 GiB", "500 MB").
struct Dimension {
  std::array<int, 6> exponent{};  // L, M, T, Theta, N, bytes

  static constexpr Dimension none() { return {}; }
  bool operator==(const Dimension&) const = default;
  Dimension operator*(const Dimension& other) const;
  Dimension operator/(const Dimension& other) const;
  Dimension pow(int p) const;
  bool isDimensionless() const { return *this == Dimension{}; }
  /// Base-unit form, e.g. "m^2", "kg m^-1 s^-1", "1" for dimensionless.
  std::string siString() const;
};

/// A unit: multiply a value in this unit by `to_si` to get SI.
struct Unit {
  double to_si = 1.0;
  Dimension dim;
};

/// A value in SI with its dimension.
struct Quantity {
  double si = 0.0;
  Dimension dim;
};

/// Thrown by the parsers; the message says what was wrong and what is allowed.
/// Callers that know the file and key wrap it into an InputError.
class UnitError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Parses a unit expression ("cm/min", "Pa s", "g/cm3", "1", "%").
Unit parseUnit(std::string_view text);

/// Parses "<number> [unit]"; an empty unit means dimensionless SI.
Quantity parseQuantity(std::string_view text);

/// Converts an SI value into `unit` (which must have the same dimension).
double fromSi(double value_in_si, std::string_view unit);

/// A human name for common dimensions ("length", "velocity", "dynamic viscosity", ...),
/// or the SI form when there is no common name.
std::string dimensionName(const Dimension& dim);

/// The list of known unit symbols, for error messages and `mmval case-doc`.
std::string knownUnitSymbols();

}  // namespace mmval
