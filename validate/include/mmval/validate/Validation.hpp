// A validation campaign (`mmval validate`): the chosen cases run one after the
// other into OUT/runs/<case.name>, cases tagged "peer" also through the
// OpenFOAM peer into OUT/runs/<case.name>-openfoam, then OUT/metrics.json,
// index.md, index.html and the full report over every run folder.
#pragma once
#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mmval/core/Case.hpp"
#include "mmval/core/CaseKind.hpp"
#include "mmval/reports/Summary.hpp"

namespace mmval::validate {

struct ValidationOptions {
  std::string out = "out/validate";  ///< as given (--out); normalised by runValidation
  std::string cases;              ///< cases folder; empty: casesFolder's search (CaseSelection.hpp)
  std::string tag = "default";    ///< --tag: which cases run (caseSelected, CaseSelection.hpp)
  bool full = false;              ///< --full: also the cases tagged "full" of that selection
  bool resume = false;            ///< keep complete runs of unchanged cases (same hash), resume interrupted ones
  bool quiet = false;             ///< no per-run progress output (the per-case lines on stderr stay)
};

struct ValidationResult {
  reports::Summary summary;  ///< one result per run folder, mmval's and the peer's, with the total wall time
  std::filesystem::path out;  ///< the normalised output folder
  std::size_t cases = 0;      ///< case files run
  int figures = 0;            ///< figures of the report
};

/// Runs the campaign. The output folder is checked (new, empty or mmval's own)
/// and locked before any case runs; the summary is rewritten after every case
/// so an interrupted validation leaves a partial one. A missing OpenFOAM marks
/// the peer "not run" instead of failing. Throws InputError for a bad cases
/// folder, an invalid case file or a tag no case carries; failing metrics are
/// reported in the result, not thrown.
ValidationResult runValidation(const ValidationOptions& options, const CaseKindRegistry& registry);

/// Writes OUT/metrics.json, OUT/index.md and OUT/index.html of `summary`, each atomically.
void writeSummary(const std::filesystem::path& out, const reports::Summary& summary);

/// The result of a case whose peer could not run, written to `dir`/result.json:
/// one informational row that says why, so the report shows "not run" instead of a gap.
nlohmann::json peerNotRun(const Case& c, const std::string& reason, const std::filesystem::path& dir);

}  // namespace mmval::validate
