// The schema of the CSV tables that more than one kind writes under the same
// file name: retention.csv and permeability.csv. This module is their only
// writer: it owns the column names, their units, the number formats and the
// derived columns (retained_fraction, k_D), so that every kind's file has the
// same header and the same invariants. docs/outputs.md ("Tables") documents
// the columns; tests/apps/OutputTablesTest.cpp checks that the two agree and
// that every kind's files follow the schema.
//
// retention.csv, one row per output frame:
//   frame, t_s, injected, inside, retained, left, retained_fraction
//   injected = inside + retained + left; retained_fraction = retained / injected (0 when none).
// permeability.csv, one row per output frame:
//   frame, t_s, k_m2, k_D, k_over_k0, pressure_drop_pa, deposited, resolves
//   k_D = k_m2 / kDarcyM2; pressure_drop_pa empty when no finite pressure drop
//   drives the flow (no flow path left).
#pragma once
#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <vector>

namespace mmval::tables {

/// m2 per darcy: 1 D = 9.869233e-13 m2 (NIST SP 811, 2008, Appendix B.8).
constexpr double kDarcyM2 = 9.869233e-13;

/// One column of a table: its name in the header and its unit ("1": a count or a ratio).
struct Column {
  const char* name;
  const char* unit;
};

/// The particle counts at one output frame. Counts are particles (or, for the
/// tracker, tracks; docs/outputs.md).
struct RetentionRow {
  std::int64_t frame = 0;  ///< output frame index (the frame column of trajectories.csv / tracks.csv)
  double t_s = 0;          ///< s
  std::int64_t injected = 0, inside = 0, retained = 0, left = 0;
};

/// The flow through the geometry at one output frame.
struct PermeabilityRow {
  std::int64_t frame = 0;  ///< output frame index
  double t_s = 0;          ///< s
  double k_m2 = 0;         ///< m2, Darcy permeability of the geometry (0: no flow path)
  double k_over_k0 = 1;    ///< k over that of the clean geometry at t = 0
  /// Pa, inlet to outlet at the set flow rate; NaN or +inf: none (no flow path), written empty.
  double pressure_drop_pa = std::numeric_limits<double>::quiet_NaN();
  std::int64_t deposited = 0;  ///< particles deposited by t_s
  std::int64_t resolves = 0;   ///< flow solves after the clean-geometry one, by t_s
};

const std::vector<Column>& retentionColumns();
const std::vector<Column>& permeabilityColumns();

/// The header line, newline included.
std::string retentionHeader();
std::string permeabilityHeader();

/// One data line, newline included. std::logic_error when the counts do not
/// balance (injected != inside + retained + left) or one is negative.
std::string formatRow(const RetentionRow& row);
/// One data line, newline included. std::logic_error when k_m2 or k_over_k0 is
/// not finite or negative, or a count is negative.
std::string formatRow(const PermeabilityRow& row);

/// A table read back: columns by header name, empty cells NaN.
using TableColumns = std::map<std::string, std::vector<double>>;

/// Parses CSV text with a header line of column names and numeric cells (an
/// empty cell is NaN). std::runtime_error naming `source`, the line and the
/// column on a cell that is not a number or a row of another length.
TableColumns parseTable(const std::string& text, const std::string& source);

}  // namespace mmval::tables
