// The paper's tables rebuilt from the runs present, next to the paper's own
// numbers (reference-data/): Table 1 (cylinder C_d against Re), Table 2
// (chip permeability and porosity), and the Table 3 permeability reductions.
// Each builder returns nothing when no run of its kind is in the report, so a
// report without that run type simply has no such table.
#pragma once
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mmval/reports/Report.hpp"

namespace mmval::reports {

struct Table {
  std::string id, title, note;
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  std::string markdown() const;
  std::string html() const;
};

/// reference-data/ beside the case files of the runs (case.file/../..), else
/// mmval's own (mmval/core/DataPaths.hpp); empty when neither exists.
std::filesystem::path findReferenceData(const ReportInput& input);

/// "I".."V" when the run is one of the paper's Table 3 cases: details.table3_case
/// (a declared field, mmval/core/DetailFields.hpp, written from the case's
/// analysis.table3_case); "" otherwise. The run's name is never read, so
/// renaming a run cannot change its row. Throws InputError when the field is
/// not a string.
std::string table3CaseOf(const nlohmann::json& details);

/// The paper's permeability reduction (percent) of a Table 3 case, if known.
std::optional<double> table3Reduction(const std::filesystem::path& reference_dir, const std::string& roman);

/// The reference setting of the paper's Table 1: the `setup` that
/// reference-data/cylinder-drag-paper-table1.toml and
/// cylinder-drag-dennis-chang.toml declare (a metric's "reference_setup").
inline constexpr const char* kTable1Setup = "unbounded-cylinder";

/// A result.json metric's declared metric name: its "metric" field, or for a
/// file written before that field existed, its "name" as it stands.
std::string metricOf(const nlohmann::json& metric);

/// True when the run is set up as the paper's Table 1 cylinder: one of its
/// c_D metrics is judged against a reference whose declared setting
/// ("reference_setup") is kTable1Setup. Decided by that field alone, never by
/// metric names or labels; a run without the field is not counted.
bool paperCylinderSetup(const nlohmann::json& run);

/// Table 1: C_d against Re, paper columns ([66]-[69], the paper's model),
/// Dennis & Chang, ours and OpenFOAM where they ran. Runs count when they have
/// details.Re and paperCylinderSetup(run); none: no table.
std::optional<Table> cylinderDragTable(const ReportInput& input, const std::filesystem::path& reference_dir);

/// Table 2: chip permeability and porosity, measured and the paper's model,
/// with every image-permeability run present.
std::optional<Table> chipTable(const ReportInput& input, const std::filesystem::path& reference_dir);

/// The paper's Table 3 trends checked on the Table 3 runs present (cases named I..V):
/// more reduction at higher velocity (I < II < III), bridging sooner at higher velocity
/// (time to the first 10 % loss), larger particles reducing more (IV < V), polydisperse
/// reducing most at one velocity (I against IV and V); the paper's numbers beside ours
/// and whether ours follow. None when fewer than two cases of a trend ran.
std::optional<Table> table3TrendsTable(const ReportInput& input, const std::filesystem::path& reference_dir);

/// Extra columns of a Table 3 row from a run's metrics: time to the first 10 %
/// permeability loss and time to clogging (k = 0), in s, "-" when it never happened.
std::vector<std::string> table3TimeColumns(const nlohmann::json& run);

/// The cheaper particle model against LIGGGHTS on a scene's shared window: one row
/// per entry of a run's details.engine_comparison (EngineComparison::toJson plus a
/// "candidate" label); none: no table.
std::optional<Table> engineComparisonTable(const ReportInput& input);

/// The value of a run's first metric whose declared metric (metricOf) is
/// `name` and whose value is a number (result.json's metrics).
std::optional<double> metricValue(const nlohmann::json& run, const std::string& name);

/// A run's time series read from a CSV with a header: column name -> values.
/// Empty map when the file is missing; throws InputError on a malformed file.
std::map<std::string, std::vector<double>> readCsvColumns(const std::filesystem::path& file);

}  // namespace mmval::reports
