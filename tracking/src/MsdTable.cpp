#include "MsdTable.hpp"

#include <cmath>
#include <iterator>

#include <fmt/format.h>

namespace mmval::tracking::detail {

namespace {

constexpr double kUm2 = 1e12;  // m^2 -> um^2

}  // namespace

std::string csvNumber(double v, const char* format) { return std::isfinite(v) ? fmt::format(fmt::runtime(format), v) : std::string(); }

std::string msdHeader() { return "lag_s,msd_um2,samples,se_um2,fit_um2\n"; }

std::string msdTable(const std::vector<MsdRow>& rows) {
  std::string out = msdHeader();
  auto it = std::back_inserter(out);
  for (const MsdRow& r : rows)
    fmt::format_to(it, "{},{},{},{},{}\n", csvNumber(r.lag_s), csvNumber(r.msd_m2 * kUm2), r.samples, csvNumber(r.se_m2 * kUm2), csvNumber(r.fit_m2 * kUm2));
  return out;
}

}  // namespace mmval::tracking::detail
