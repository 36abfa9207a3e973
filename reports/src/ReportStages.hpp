// Internal to mmval::reports: the stages writeReport runs, in order (Report.cpp).
// Each stage reads the collected runs and comparisons it is given and returns
// what it makes; only FigureSink and the writers touch the output folder.
//
//   figures:  crossCaseFigures -> forceHistoryFigures -> comparisonFigures
//             -> paperFigures -> sweepFigures -> physicsFigures -> runImages   (FigureSink)
//   tables:   paperTables, regionTables, alignmentNotes, sweepTables (Parts)
//   files:    writeMetricsJson, writeMarkdown, writePages (Pages.cpp)
#pragma once
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "mmval/reports/Plot.hpp"
#include "mmval/reports/Report.hpp"
#include "mmval/reports/Tables.hpp"
#include "ReportParts.hpp"

namespace mmval::reports::detail {

/// A file name for figures/: the id with anything but [A-Za-z0-9._-] as '-'.
std::string fileId(const std::string& id);

/// The report's figures, in the order they are added, and their files under
/// <out>/figures/ (created by the constructor).
class FigureSink {
 public:
  /// `plots`: gnuplot is available; without it addPlot and addRendered do nothing.
  FigureSink(std::filesystem::path out, bool plots);
  bool plots() const { return m_plots; }
  const std::filesystem::path& out() const { return m_out; }
  const std::vector<Figure>& figures() const { return m_figures; }

  /// A plot rendered to figures/<id>.svg with its data as figures/<id>.csv.
  /// `owner`: the page key of the case page that shows it; "" for paper.html.
  void addPlot(const std::string& id, const std::string& caption, const Plot& p, const std::string& owner = {});
  /// A figure whose SVG is already rendered (f.svg) and whose data is a run's
  /// own file (f.data, relative to the report); written to figures/<id>.svg.
  void addRendered(Figure f);
  /// A PNG copied to figures/<id>.png, once per source file (a compare-tracks
  /// run lists the images its comparison folder also holds).
  void addImage(const std::string& id, const std::string& caption, const std::filesystem::path& png, const std::string& owner,
                std::string data = {}, std::string data_label = {}, std::string colour_bar = {});

 private:
  std::filesystem::path m_out;
  bool m_plots;
  std::vector<Figure> m_figures;
  std::vector<std::filesystem::path> m_images_seen;
};

/// The numeric columns of a CSV with a header row ("t_s,experiment,simulation"
/// as compare writes them); a cell that is not a number is NaN.
std::vector<std::vector<double>> readColumns(const std::filesystem::path& csv);

/// The run whose folder is the comparison's folder (a compare-tracks run), or null.
nlohmann::json runOf(const ReportInput& input, const ComparisonInput& c);
/// The page key of the page that shows a comparison: its run's, else "compare-<name>".
std::string ownerOf(const ReportInput& input, const ComparisonInput& c);

// ---- figures (ReportFigures.cpp, ReportRunFigures.cpp) ----

/// paper.html's figures across cases: speed against error over resolution
/// ladders, and c_D against Re of the runs set up as the paper's Table 1
/// (paperCylinderSetup) with the references of Table 1 (from `reference_dir`).
void crossCaseFigures(const ReportInput& input, const std::filesystem::path& reference_dir, FigureSink& sink);
/// c_D and c_L against time of each unsteady run (its forces.csv), on its case page.
void forceHistoryFigures(const ReportInput& input, FigureSink& sink);
/// Each comparison's time series, speed histogram and images, its sides named by their inputs.
void comparisonFigures(const ReportInput& input, FigureSink& sink);
/// The paper's permeability and retention figures; returns the metrics the
/// permeability figure derives (for metrics.json) and the Table 3 rows.
struct PaperFigureResults {
  nlohmann::json metrics = nlohmann::json::array();
  std::vector<std::vector<std::string>> reduction_rows;
};
PaperFigureResults paperFigures(const ReportInput& input, const std::filesystem::path& reference_dir, FigureSink& sink);
/// Each run's measured values against its theory (PhysicsFigures.hpp), on its case page.
void physicsFigures(const ReportInput& input, const std::filesystem::path& reference_dir, FigureSink& sink);
/// The PNG files each result.json lists; speed fields get a colour bar.
void runImages(const ReportInput& input, FigureSink& sink);
/// Each sweep's metrics against its grid axis (else its first axis), one series per
/// step value and other setting, error bars the seeds' standard error: the metrics the
/// sweep was asked to show (--metric), else every metric whose mean varies. On its page.
void sweepFigures(const ReportInput& input, FigureSink& sink);

// ---- tables and files (ReportWriters.cpp) ----

/// The paper's tables rebuilt from the runs present (Tables.hpp), Table 3 from `reduction_rows`.
std::vector<Table> paperTables(const ReportInput& input, const std::filesystem::path& reference_dir,
                               const std::vector<std::vector<std::string>>& reduction_rows);
/// Mean speed per region of each comparison that has regions: (page key, table).
std::vector<std::pair<std::string, Table>> regionTables(const ReportInput& input);
/// Each sweep's uncertainty (sweep.json): per metric and setting of the other axes, the
/// value at the finest grid and step with its seed, grid and step parts, combined, and the verdict.
std::vector<std::pair<std::string, Table>> sweepTables(const ReportInput& input);
/// One line per comparison that registered its frames to the mask.
std::vector<std::string> alignmentNotes(const ReportInput& input);
/// <out>/metrics.json: every run's and comparison's metrics, `extra_metrics`, the tables.
void writeMetricsJson(const ReportInput& input, const Parts& parts, const nlohmann::json& extra_metrics, const std::filesystem::path& out);
/// <out>/report.md: the summary, the comparisons, the tables, the alignments and the figure list.
void writeMarkdown(const ReportInput& input, const Parts& parts, const std::filesystem::path& out);

}  // namespace mmval::reports::detail
