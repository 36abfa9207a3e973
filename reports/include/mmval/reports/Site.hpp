// The pieces of the report's HTML pages: the shared head and navigation, the
// provenance block every page carries, colour bars for field images, CSV
// files behind plots, comparisons named by their inputs, and the check that
// every link of the written pages resolves.
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mmval/reports/Plot.hpp"
#include "mmval/reports/Report.hpp"

namespace mmval::reports {

/// Versions and stamp of the runs behind a report, and of the report itself.
/// Fields a run did not record read "not recorded".
struct Provenance {
  std::string git_hash = "not recorded";  ///< without the "-dirty" suffix
  std::string dirty = "not recorded";     ///< "yes", "no" or "not recorded"
  std::string run_date = "not recorded", report_date, host = "not recorded", compiler = "not recorded", build_type = "not recorded";
  std::string opencv = "not recorded", petsc = "not recorded", openfoam = "not recorded", liggghts = "not recorded", gnuplot = "not found";
  std::string mmval_version = "not recorded";
  /// True when the runs disagree on git hash or host (the block then lists each run's own on its case page).
  bool mixed = false;
};

/// Provenance of one run's result.json (its "provenance" object and, for the
/// OpenFOAM and LIGGGHTS versions, details.solver / details.liggghts_version
/// when recorded); the report's own date and gnuplot version filled in.
Provenance provenanceOf(const nlohmann::json& result);
/// Provenance over all runs of a report: the first run's, `mixed` when others differ.
Provenance provenanceOf(const ReportInput& input);

/// The provenance block (HTML, id="provenance").
std::string provenanceHtml(const Provenance& p);

/// Page head with the title, the stylesheet and the navigation bar; `root` is
/// the relative path from the page to the report's folder ("" or "../").
std::string pageHead(const std::string& title, const std::string& root);
/// Closing tags, with the script that counts decoded images (id="image-status").
std::string pageFoot();

/// A colour bar (viridis, as simulate's field PNGs) from `lo` to `hi` in
/// `unit`, as inline HTML; `label` names the quantity.
std::string colourBarHtml(double lo, double hi, const std::string& unit, const std::string& label);

/// Largest cell speed |U| of an mmval .vtr (binary or ASCII, CellData "U"); NaN when
/// the file is missing, unreadable or has no "U" (the colour bar then says "not recorded").
double maxSpeedOfVtr(const std::filesystem::path& vtr);
/// Largest cell speed |U| over the fluid cells (solid < 0.5) of the middle cell layer
/// k = nz / 2 of a 3D mmval .vtr (fields-3d.vtr): the range simulate scales its
/// mid-depth speed picture to. NaN when the file is missing or unreadable, or not 3D.
double maxSpeedOnMidDepthPlane(const std::filesystem::path& vtr);

/// The data behind a plot as CSV: one row per point, columns series, x, y
/// (with the plot's axis labels in a comment line first).
std::string plotCsv(const Plot& plot);

/// How a comparison's two inputs are named on every page: what the
/// "experiment" and "simulation" sides really are, and the comparison's kind:
/// "pipeline check" when the experiment side is a tracked rendering of a
/// simulation run, "experiment vs simulation" only for real footage.
struct ComparisonNames {
  std::string kind;       ///< "Pipeline check" or "Experiment vs simulation" or "Tracks vs simulation"
  std::string reference;  ///< the side compare calls "experiment"
  std::string candidate;  ///< the side compare calls "simulation"
  std::string explanation;
  std::string reference_short, candidate_short;  ///< for plot keys
};
/// Names of a compare-tracks run (its resolved_case.inputs, and the kinds of
/// the runs it names) or of a compare folder (`run` null: inputs not recorded).
ComparisonNames comparisonNames(const nlohmann::json& run, const ReportInput& input);

/// Links (href and src) of every .html page under `dir` that do not resolve:
/// a relative file that does not exist, or a "#fragment" with no element of
/// that id in the target page. data:, http(s): and mailto: links are not checked
/// (the report has none but DOIs). Each entry: "page: link".
std::vector<std::string> brokenLinks(const std::filesystem::path& dir);

/// "doi:10.x/y" and "https://doi.org/..." in a source text become links; the rest is escaped.
std::string linkDois(const std::string& text);

}  // namespace mmval::reports
