#include "MsdTable.hpp"

#include <cmath>
#include <iterator>

#include <fmt/format.h>

namespace mmval::tracking::detail {

namespace {

constexpr double kUm2 = 1e12;  // m^2 -> um^2

/// A cell of 6 significant digits, or empty for NaN / infinity (CSV readers take an
/// empty cell as missing, where "nan" would be a string to some).
std::string cell(double v) { return std::isfinite(v) ? fmt::format("{:.6g}", v) : std::string(); }

}  // namespace

std::string msdHeader() { return "lag_s,msd_um2,samples,se_um2,fit_um2\n"; }

std::string msdTable(const std::vector<MsdRow>& rows) {
  std::string out = msdHeader();
  auto it = std::back_inserter(out);
  for (const MsdRow& r : rows)
    fmt::format_to(it, "{},{},{},{},{}\n", cell(r.lag_s), cell(r.msd_m2 * kUm2), r.samples, cell(r.se_m2 * kUm2), cell(r.fit_m2 * kUm2));
  return out;
}

}  // namespace mmval::tracking::detail
