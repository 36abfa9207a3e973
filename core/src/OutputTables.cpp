#include "mmval/core/OutputTables.hpp"

#include <cmath>
#include <cstdlib>
#include <sstream>
#include <stdexcept>

#include <fmt/format.h>

namespace mmval::tables {

namespace {

std::string headerOf(const std::vector<Column>& columns) {
  std::string h;
  for (const auto& c : columns) {
    if (!h.empty()) h += ',';
    h += c.name;
  }
  return h + '\n';
}

std::vector<std::string> splitCells(const std::string& line) {
  std::vector<std::string> cells;
  std::string cell;
  std::istringstream in(line);
  while (std::getline(in, cell, ',')) cells.push_back(cell);
  if (!line.empty() && line.back() == ',') cells.emplace_back();
  return cells;
}

}  // namespace

const std::vector<Column>& retentionColumns() {
  static const std::vector<Column> c = {{"frame", "1"},  {"t_s", "s"},  {"injected", "1"},         {"inside", "1"},
                                        {"retained", "1"}, {"left", "1"}, {"retained_fraction", "1"}};
  return c;
}

const std::vector<Column>& permeabilityColumns() {
  static const std::vector<Column> c = {{"frame", "1"},     {"t_s", "s"},          {"k_m2", "m2"},      {"k_D", "D"},
                                        {"k_over_k0", "1"}, {"pressure_drop_pa", "Pa"}, {"deposited", "1"}, {"resolves", "1"}};
  return c;
}

std::string retentionHeader() { return headerOf(retentionColumns()); }
std::string permeabilityHeader() { return headerOf(permeabilityColumns()); }

std::string formatRow(const RetentionRow& r) {
  if (r.injected < 0 || r.inside < 0 || r.retained < 0 || r.left < 0 || r.injected != r.inside + r.retained + r.left)
    throw std::logic_error(fmt::format("retention.csv at t = {} s: counts do not balance: injected {} != inside {} + retained {} + left {}", r.t_s,
                                       r.injected, r.inside, r.retained, r.left));
  const double fraction = r.injected > 0 ? static_cast<double>(r.retained) / static_cast<double>(r.injected) : 0.0;
  return fmt::format("{},{:.9g},{},{},{},{},{:.9g}\n", r.frame, r.t_s, r.injected, r.inside, r.retained, r.left, fraction);
}

std::string formatRow(const PermeabilityRow& r) {
  if (!std::isfinite(r.k_m2) || r.k_m2 < 0 || !std::isfinite(r.k_over_k0) || r.k_over_k0 < 0 || r.deposited < 0 || r.resolves < 0)
    throw std::logic_error(fmt::format("permeability.csv at t = {} s: k = {} m2, k/k0 = {}, deposited {}, resolves {}", r.t_s, r.k_m2,
                                       r.k_over_k0, r.deposited, r.resolves));
  const std::string dp = std::isfinite(r.pressure_drop_pa) ? fmt::format("{:.9g}", r.pressure_drop_pa) : std::string();
  return fmt::format("{},{:.9g},{:.9g},{:.9g},{:.9g},{},{},{}\n", r.frame, r.t_s, r.k_m2, r.k_m2 / kDarcyM2, r.k_over_k0, dp, r.deposited,
                     r.resolves);
}

TableColumns parseTable(const std::string& text, const std::string& source) {
  std::istringstream in(text);
  std::string line;
  if (!std::getline(in, line)) throw std::runtime_error(source + ": empty, expected a header line");
  const std::vector<std::string> names = splitCells(line);
  TableColumns cols;
  for (const auto& n : names) cols[n];
  for (int line_no = 2; std::getline(in, line); ++line_no) {
    if (line.empty()) continue;
    const std::vector<std::string> cells = splitCells(line);
    if (cells.size() != names.size())
      throw std::runtime_error(fmt::format("{}:{}: {} cells, expected {} (as the header)", source, line_no, cells.size(), names.size()));
    for (std::size_t i = 0; i < cells.size(); ++i) {
      double v = std::nan("");
      if (!cells[i].empty()) {
        char* end = nullptr;
        v = std::strtod(cells[i].c_str(), &end);
        if (end == cells[i].c_str() || *end != '\0')
          throw std::runtime_error(fmt::format("{}:{}: column {}: \"{}\" is not a number", source, line_no, names[i], cells[i]));
      }
      cols[names[i]].push_back(v);
    }
  }
  return cols;
}

}  // namespace mmval::tables
