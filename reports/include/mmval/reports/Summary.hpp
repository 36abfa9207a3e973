// The validation summary: one row per metric of every case run, with its
// value, reference, error, tolerance, pass/fail and the case's cost.
#pragma once
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace mmval::reports {

/// Builds the summary from the result.json documents of several runs.
struct Summary {
  std::vector<nlohmann::json> results;  ///< parsed result.json documents
  double total_wall_seconds = 0.0;  ///< s, the session that produced the summary (validate: its elapsed time)

  /// {"cases": [...], "metrics": [{case, name, value, unit, reference, error, tolerance, pass}], "all_pass"}
  nlohmann::json metricsJson() const;
  std::string markdown() const;
  /// Self-contained HTML page (no network).
  std::string html() const;
  /// Plain-text table for the terminal.
  std::string text() const;
  int failures() const;
  /// s, the runs' own wall times (result.json cost.wall_seconds) added up.
  double runsWallSeconds() const;
  /// "total wall time X s" over the runs; when the session's time differs (runs kept by
  /// `validate --resume` ran in an earlier session), that time too, so neither is mistaken for the other.
  std::string wallTimeText() const;
};

/// Text for HTML: & < > and " as entities.
std::string htmlEscape(const std::string& s);
/// Formats a metric's reference (point, interval) for tables.
std::string referenceText(const nlohmann::json& metric);
/// Formats a metric's error: relative as %, absolute in the metric's unit.
std::string errorText(const nlohmann::json& metric);
/// Who computed a run's numbers: details.solver (mmval/core/DetailFields.hpp), "mmval" when absent.
std::string solverOf(const nlohmann::json& run);

}  // namespace mmval::reports
