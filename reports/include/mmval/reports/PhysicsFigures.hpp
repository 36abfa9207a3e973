// Figures of the physics checks (cases tagged "physics", kinds "physics-..."):
// each run's measured values against its theory, drawn from the CSV the run
// wrote, for the run's own case page. Which figures a run gets follows its case
// kind (result.json case.kind), never the spelling of its metric names.
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mmval/reports/Plot.hpp"

namespace mmval::reports {

/// One figure of a physics-check run: the plot, its caption (what the
/// reference is) and the run's CSV it is drawn from.
struct CheckFigure {
  std::string id;  ///< unique within the run, e.g. "height-histogram"
  std::string caption;
  Plot plot;
  std::filesystem::path data;  ///< the run's CSV behind the plot
};

/// The figures of a physics-check run (a result.json with "run_dir"), read from
/// the CSVs in its run folder; `reference_dir` is reference-data/ (tabulated
/// theory some checks are drawn against; may be empty). A run of another kind
/// gets none; a CSV that is missing or lacks a column leaves its figure out with
/// a note on stderr. Throws InputError (from readCsvColumns) on a malformed CSV.
std::vector<CheckFigure> physicsCheckFigures(const nlohmann::json& run, const std::filesystem::path& reference_dir);

}  // namespace mmval::reports
