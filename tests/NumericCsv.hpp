// Reads a CSV of numbers with one header line (trackpy's reference outputs in
// ../shared/data/trackpy-tests): one vector per non-empty row.
#pragma once
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace mmval::test {

inline std::vector<std::vector<double>> readNumericCsv(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::string line;
  std::getline(in, line);
  std::vector<std::vector<double>> rows;
  while (std::getline(in, line)) {
    std::stringstream ss(line);
    std::string cell;
    std::vector<double> r;
    while (std::getline(ss, cell, ',')) r.push_back(std::stod(cell));
    if (!r.empty()) rows.push_back(r);
  }
  return rows;
}

}  // namespace mmval::test
