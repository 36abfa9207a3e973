// Internal to mmval::reports: what writeReport's stages hand to the page writer.
#pragma once
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "mmval/reports/Report.hpp"
#include "mmval/reports/Tables.hpp"

namespace mmval::reports::detail {

/// A figure of the report: an SVG plot (with the CSV of its data) or a PNG image
/// copied into figures/ (with the file behind it and, for fields, a colour bar).
struct Figure {
  std::string id, caption;
  std::string owner;       ///< case or comparison name whose page shows it; "" for the cross-case page
  std::string svg;         ///< inline SVG of a plot; empty for images
  std::string image;       ///< file name under figures/ of an image
  std::string data;        ///< file behind the figure, relative to the report folder (figures/<id>.csv, or a run's file)
  std::string data_label;  ///< what `data` is ("CSV", "fields (.vtr)", ...)
  std::string colour_bar;  ///< HTML of a colour bar beside an image, if it shows a field
};

struct Parts {
  std::vector<Figure> figures;
  std::vector<Table> tables;
  std::vector<std::pair<std::string, Table>> case_tables;  ///< tables of one case's page: (case, table)
  std::vector<std::pair<std::string, Table>> sweep_tables; ///< each sweep's uncertainty table: (its page key, sweepPageKey)
  std::vector<std::string> alignments;
  bool plots = true;
};

/// The report's pages: index.html (summary), paper.html (tables and cross-case
/// figures), cases/<name>.html (one per run and per compare folder not run as a case).
void writePages(const ReportInput& input, const Parts& parts, const std::filesystem::path& out);

/// The key of a run's page and figures: its run folder's name (unique in a validation:
/// a peer run of a case is "<case>-openfoam"), else the case name.
std::string pageKey(const nlohmann::json& run);

/// A path as an href from `from_dir`: relative, with ' ', '#', '%' and '?' percent-encoded.
std::string relativeLink(const std::filesystem::path& target, const std::filesystem::path& from_dir);

/// The key of a sweep's page and figures: "sweep-<folder name>".
std::string sweepPageKey(const SweepInput& sweep);

/// File name of a case's page under cases/.
std::string casePageName(const std::string& name);

}  // namespace mmval::reports::detail
