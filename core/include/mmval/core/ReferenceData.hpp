// Reference values from the literature, stored as data in reference-data/
// (format "mmval-reference/1", described in reference-data/README.md). One
// loader reads and checks every file: required keys, units that parse,
// sources that resolve, a point value or an interval per row.
#pragma once
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "mmval/core/Units.hpp"

namespace mmval {

/// A condition value in a row's `at` table: a number or a label.
using AtValue = std::variant<double, std::string>;
using AtMap = std::map<std::string, AtValue>;

std::string toString(const AtMap& at);

struct ReferenceSource {
  std::string id, citation, doi, locator;
};

struct ReferenceRow {
  std::string quantity;
  AtMap at;
  std::optional<double> value, low, high, uncertainty;  ///< in `unit`
  std::string unit;                                     ///< as written ("1" when dimensionless)
  Unit unit_si;                                         ///< parsed unit
  std::string source;                                   ///< id into sources
  std::string note;
  int line = 0;
  /// True when every entry of `conditions` is in `at` with the same value
  /// (numbers to a relative 1e-9).
  bool matches(const AtMap& conditions) const;
};

struct ReferenceFile {
  std::filesystem::path path;
  std::string title, description;
  /// Optional: the physical setting every row describes ("unbounded-cylinder",
  /// "confined-channel-cylinder"); a reader decides what a value is comparable
  /// with from this field, never from names or titles.
  std::string setup;
  std::vector<ReferenceSource> sources;
  std::vector<ReferenceRow> rows;
  const ReferenceSource& source(const std::string& id) const;
  /// Rows with this quantity matching the conditions.
  std::vector<const ReferenceRow*> find(const std::string& quantity, const AtMap& conditions) const;
};

/// Loads and checks a reference file; throws InputError naming file, line and key.
/// Results are cached per path for the life of the process.
const ReferenceFile& loadReferenceFile(const std::filesystem::path& path);

}  // namespace mmval
