// The validation report: a self-contained, offline set of HTML pages (a
// summary, the paper's tables with the figures across cases, one page per
// case; inline SVG plots from gnuplot with their CSV, PNG images copied
// beside them), the same content as Markdown, and metrics.json so two runs
// can be diffed. Pages link each run's folder and files by relative paths.
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mmval/reports/Summary.hpp"

namespace mmval::reports {

/// A track comparison folder written by `mmval compare` or a compare-tracks run
/// (pages name its two sides by their inputs: Site.hpp, comparisonNames).
struct ComparisonInput {
  std::string name;
  std::filesystem::path dir;
  nlohmann::json metrics;  ///< its metrics.json
  bool also_run = false;   ///< the folder is also a run (a compare-tracks case): its metrics are the run's
};

/// A sweep folder written by `mmval sweep` (docs/outputs.md, "The sweep folder"):
/// its sweep.json, read for each metric's value with its seed, grid and step parts.
struct SweepInput {
  std::string name;  ///< the folder's name
  std::filesystem::path dir;
  nlohmann::json sweep;      ///< its sweep.json (schema mmval-sweep/1)
  nlohmann::json first_run;  ///< result.json of its first run (provenance), null when none is complete
};

struct ReportInput {
  Summary summary;                          ///< result.json of every run
  std::vector<ComparisonInput> comparisons;
  std::vector<SweepInput> sweeps;
};

/// Finds runs (folders with result.json), comparisons (metrics.json of
/// schema mmval-compare/1) and sweeps (sweep.json; a sweep's runs/ are read
/// through it, not as runs) in the given folders and their runs/ subfolders.
/// Throws InputError naming a folder that holds neither, and naming the file
/// and field of a result.json or metrics.json that is unreadable, empty, not
/// JSON, larger than kMaxInputBytes or of the wrong shape (JsonShape.hpp).
/// Likewise a sweep.json (checkSweepShape).
ReportInput collect(const std::vector<std::filesystem::path>& dirs);

/// Writes index.html (summary, failures first), paper.html, cases/<run>.html
/// (with a copy of each case file), report.md, metrics.json and figures/
/// (*.svg with *.csv, *.png) into `out`. Returns the number of figures.
int writeReport(const ReportInput& input, const std::filesystem::path& out);

/// Metrics of `b` whose value moved beyond its tolerance relative to `a`
/// (or whose pass/fail changed), as a Markdown table. Both must pass
/// checkMetricsListShape (InputError otherwise).
std::string diffMetrics(const nlohmann::json& a, const nlohmann::json& b);

/// diffMetrics of two files (a report's, compare's metrics.json or a
/// result.json); throws InputError naming the file and field when one is
/// missing, empty, not JSON, too large or of the wrong shape.
std::string diffMetricFiles(const std::filesystem::path& before, const std::filesystem::path& after);

/// Base64 for inlining images.
std::string base64(const std::string& bytes);

}  // namespace mmval::reports
