// Figures of the paper's coupled results built from the runs present:
// normalised permeability against time (every run that wrote permeability.csv,
// the paper's Table 3 reductions as labelled points) and the retained
// fraction against time (runs that wrote retention.csv, comparisons'
// retention_time.csv, the micromodel's 42.3 % / 44.1 % as levels). Each
// returns no plot when no run of that type is present.
#pragma once
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mmval/reports/Plot.hpp"
#include "mmval/reports/Report.hpp"

namespace mmval::reports {

struct PermeabilityFigure {
  std::optional<Plot> plot;
  /// run, Table 3 case, t end (s), k/k0 at end, reduction, paper, difference
  std::vector<std::vector<std::string>> rows;
  /// "permeability_reduction" (%) per run, the paper's value as reference when known
  nlohmann::json metrics = nlohmann::json::array();
  /// Runs whose Table 3 reduction is drawn (filled diamonds with labels); the caption says so only when > 0.
  int paper_points = 0;
};

/// Reads <run_dir>/permeability.csv in the schema of mmval/core/OutputTables.hpp
/// (docs/outputs.md, "Tables"). Files without those columns are skipped with a
/// note on stderr.
PermeabilityFigure permeabilityFigure(const ReportInput& input, const std::filesystem::path& reference_dir);

/// Reads <run_dir>/retention.csv in the schema of mmval/core/OutputTables.hpp
/// and each comparison's retention_time.csv.
std::optional<Plot> retentionFigure(const ReportInput& input, const std::filesystem::path& reference_dir);

}  // namespace mmval::reports
