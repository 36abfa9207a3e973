#include "mmval/core/Units.hpp"

#include <cctype>
#include <charconv>
#include <cmath>
#include <map>
#include <stdexcept>
#include <vector>

namespace mmval {
namespace {

constexpr Dimension dimOf(int L, int M, int T, int Th = 0, int N = 0, int B = 0) { return Dimension{{L, M, T, Th, N, B}}; }

const Dimension kLength = dimOf(1, 0, 0);
const Dimension kMass = dimOf(0, 1, 0);
const Dimension kTime = dimOf(0, 0, 1);
const Dimension kVolume = dimOf(3, 0, 0);
const Dimension kArea = dimOf(2, 0, 0);
const Dimension kPressure = dimOf(-1, 1, -2);
const Dimension kForce = dimOf(1, 1, -2);
const Dimension kEnergy = dimOf(2, 1, -2);
const Dimension kViscosity = dimOf(-1, 1, -1);
const Dimension kFrequency = dimOf(0, 0, -1);
const Dimension kMemory = dimOf(0, 0, 0, 0, 0, 1);

// Base symbols; SI prefixes are listed explicitly so that "min" is not "milli-in".
const std::map<std::string, Unit, std::less<>>& unitTable() {
  static const std::map<std::string, Unit, std::less<>> table = {
      {"1", {1.0, {}}},
      {"%", {1e-2, {}}},
      {"rad", {1.0, {}}},
      {"deg", {M_PI / 180.0, {}}},
      {"m", {1.0, kLength}},
      {"km", {1e3, kLength}},
      {"cm", {1e-2, kLength}},
      {"mm", {1e-3, kLength}},
      {"um", {1e-6, kLength}},
      {"\u00b5m", {1e-6, kLength}},  // micro sign
      {"\u03bcm", {1e-6, kLength}},  // Greek small letter mu, what most keyboards give
      {"micron", {1e-6, kLength}},
      {"microns", {1e-6, kLength}},
      {"nm", {1e-9, kLength}},
      {"kg", {1.0, kMass}},
      {"g", {1e-3, kMass}},
      {"mg", {1e-6, kMass}},
      {"ug", {1e-9, kMass}},
      {"s", {1.0, kTime}},
      {"ms", {1e-3, kTime}},
      {"us", {1e-6, kTime}},
      {"ns", {1e-9, kTime}},
      {"min", {60.0, kTime}},
      {"h", {3600.0, kTime}},
      {"K", {1.0, dimOf(0, 0, 0, 1)}},
      {"mol", {1.0, dimOf(0, 0, 0, 0, 1)}},
      {"L", {1e-3, kVolume}},
      {"mL", {1e-6, kVolume}},
      {"uL", {1e-9, kVolume}},
      {"\u00b5L", {1e-9, kVolume}},
      {"\u03bcL", {1e-9, kVolume}},
      {"nL", {1e-12, kVolume}},
      {"Pa", {1.0, kPressure}},
      {"kPa", {1e3, kPressure}},
      {"MPa", {1e6, kPressure}},
      {"GPa", {1e9, kPressure}},
      {"bar", {1e5, kPressure}},
      {"atm", {101325.0, kPressure}},
      {"psi", {6894.757293168, kPressure}},
      {"N", {1.0, kForce}},
      {"mN", {1e-3, kForce}},
      {"uN", {1e-6, kForce}},
      {"nN", {1e-9, kForce}},
      {"J", {1.0, kEnergy}},
      {"D", {9.869233e-13, kArea}},
      {"mD", {9.869233e-16, kArea}},
      {"P", {0.1, kViscosity}},
      {"cP", {1e-3, kViscosity}},
      {"Hz", {1.0, kFrequency}},
      {"B", {1.0, kMemory}},
      {"kB", {1e3, kMemory}},
      {"MB", {1e6, kMemory}},
      {"GB", {1e9, kMemory}},
      {"TB", {1e12, kMemory}},
      {"KiB", {1024.0, kMemory}},
      {"MiB", {1048576.0, kMemory}},
      {"GiB", {1073741824.0, kMemory}},
      {"TiB", {1099511627776.0, kMemory}},
  };
  return table;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}

// One factor such as "m", "cm3", "m^2", "s^-1".
Unit parseFactor(std::string_view factor, std::string_view whole) {
  std::string_view symbol = factor;
  int exponent = 1;
  std::size_t caret = factor.find('^');
  std::string_view exp_text;
  if (caret != std::string_view::npos) {
    symbol = factor.substr(0, caret);
    exp_text = factor.substr(caret + 1);
  } else {
    std::size_t i = factor.size();
    while (i > 0 && (std::isdigit(static_cast<unsigned char>(factor[i - 1])) || factor[i - 1] == '-')) --i;
    // "1" alone is the dimensionless unit, not an exponent.
    if (i > 0 && i < factor.size()) {
      symbol = factor.substr(0, i);
      exp_text = factor.substr(i);
    }
  }
  if (!exp_text.empty()) {
    auto [ptr, ec] = std::from_chars(exp_text.data(), exp_text.data() + exp_text.size(), exponent);
    // |exponent| <= 12 covers every physical unit and keeps the dimension arithmetic far from int overflow.
    if (ec != std::errc{} || ptr != exp_text.data() + exp_text.size() || exponent == 0 || exponent > 12 || exponent < -12) {
      throw UnitError("bad exponent '" + std::string(exp_text) + "' in unit '" + std::string(whole) + "'");
    }
  }
  auto it = unitTable().find(symbol);
  if (it == unitTable().end()) {
    throw UnitError("unknown unit '" + std::string(symbol) + "' in '" + std::string(whole) +
                    "' (known: " + knownUnitSymbols() + ")");
  }
  return Unit{std::pow(it->second.to_si, exponent), it->second.dim.pow(exponent)};
}

}  // namespace

Dimension Dimension::operator*(const Dimension& other) const {
  Dimension d;
  for (std::size_t i = 0; i < exponent.size(); ++i) d.exponent[i] = exponent[i] + other.exponent[i];
  return d;
}

Dimension Dimension::operator/(const Dimension& other) const { return *this * other.pow(-1); }

Dimension Dimension::pow(int p) const {
  Dimension d;
  for (std::size_t i = 0; i < exponent.size(); ++i) d.exponent[i] = exponent[i] * p;
  return d;
}

std::string Dimension::siString() const {
  static const char* base[] = {"m", "kg", "s", "K", "mol", "B"};
  // kg first reads more naturally ("kg m^-1 s^-1").
  static const int order[] = {1, 0, 2, 3, 4, 5};
  std::string out;
  for (int i : order) {
    int e = exponent[static_cast<std::size_t>(i)];
    if (e == 0) continue;
    if (!out.empty()) out += ' ';
    out += base[i];
    if (e != 1) out += "^" + std::to_string(e);
  }
  return out.empty() ? "1" : out;
}

Unit parseUnit(std::string_view text) {
  std::string_view whole = trim(text);
  if (whole.empty()) return Unit{};
  Unit result;
  bool denominator = false;
  std::string token;
  auto flush = [&]() {
    if (token.empty()) return;
    Unit f = parseFactor(token, whole);
    for (std::size_t i = 0; i < result.dim.exponent.size(); ++i)
      if (std::abs(result.dim.exponent[i]) > 48)
        throw UnitError("unit '" + std::string(whole) + "' has a dimension exponent beyond 48; no physical quantity needs one");
    if (denominator) {
      result.to_si /= f.to_si;
      result.dim = result.dim / f.dim;
    } else {
      result.to_si *= f.to_si;
      result.dim = result.dim * f.dim;
    }
    token.clear();
  };
  for (std::size_t i = 0; i < whole.size(); ++i) {
    char c = whole[i];
    if (std::isspace(static_cast<unsigned char>(c)) || c == '*' || c == '.') {
      flush();
    } else if (c == '/') {
      flush();
      if (denominator) throw UnitError("more than one '/' in unit '" + std::string(whole) + "'; write 'a/b c' for a/(b c)");
      denominator = true;
    } else {
      token += c;
    }
  }
  flush();
  return result;
}

Quantity parseQuantity(std::string_view text) {
  std::string_view s = trim(text);
  if (s.empty()) throw UnitError("empty quantity; expected a number with a unit, e.g. \"5 um\"");
  double value = 0.0;
  const char* begin = s.data();
  const char* end = s.data() + s.size();
  auto [ptr, ec] = std::from_chars(begin, end, value);
  if (ec != std::errc{}) throw UnitError("'" + std::string(s) + "' does not start with a number");
  Unit u = parseUnit(std::string_view(ptr, static_cast<std::size_t>(end - ptr)));
  if (!std::isfinite(value)) throw UnitError("'" + std::string(s) + "' is not a finite number");
  return Quantity{value * u.to_si, u.dim};
}

double fromSi(double value_in_si, std::string_view unit) { return value_in_si / parseUnit(unit).to_si; }

std::string dimensionName(const Dimension& dim) {
  static const std::vector<std::pair<Dimension, const char*>> names = {
      {Dimension{}, "dimensionless number"},
      {kLength, "length"},
      {kArea, "area (e.g. permeability)"},
      {kMemory, "memory (bytes)"},
      {kVolume, "volume"},
      {kMass, "mass"},
      {kTime, "time"},
      {kFrequency, "frequency"},
      {dimOf(1, 0, -1), "velocity"},
      {dimOf(1, 0, -2), "acceleration"},
      {dimOf(3, 0, -1), "volumetric flow rate"},
      {dimOf(-3, 1, 0), "density"},
      {dimOf(-3, 0, 0), "number concentration"},
      {kPressure, "pressure"},
      {kForce, "force"},
      {kEnergy, "energy"},
      {kViscosity, "dynamic viscosity"},
      {dimOf(2, 0, -1), "diffusivity or kinematic viscosity"},
      {dimOf(0, 0, 0, 1), "temperature"},
      {dimOf(-2, 1, -2), "pressure gradient"},
  };
  for (const auto& [d, name] : names) {
    if (d == dim) return name;
  }
  return "quantity in " + dim.siString();
}

std::string knownUnitSymbols() {
  std::string out;
  for (const auto& [symbol, unit] : unitTable()) {
    if (!out.empty()) out += ", ";
    out += symbol;
  }
  return out;
}

}  // namespace mmval
