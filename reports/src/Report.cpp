#include "mmval/reports/Report.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <limits>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>

#include <fmt/format.h>

#include "mmval/reports/Summary.hpp"

#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/reports/InputFiles.hpp"
#include "mmval/reports/JsonShape.hpp"
#include "mmval/reports/Plot.hpp"
#include "mmval/reports/PaperFigures.hpp"
#include "mmval/reports/PhysicsFigures.hpp"
#include "mmval/reports/Tables.hpp"
#include "mmval/reports/Site.hpp"
#include "ReportParts.hpp"

namespace fs = std::filesystem;

namespace mmval::reports {

std::string base64(const std::string& in) {
  static const char* t = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  std::size_t i = 0;
  for (; i + 2 < in.size(); i += 3) {
    const unsigned v = (static_cast<unsigned char>(in[i]) << 16) | (static_cast<unsigned char>(in[i + 1]) << 8) | static_cast<unsigned char>(in[i + 2]);
    out += {t[v >> 18], t[(v >> 12) & 63], t[(v >> 6) & 63], t[v & 63]};
  }
  if (i + 1 == in.size()) {
    const unsigned v = static_cast<unsigned char>(in[i]) << 16;
    out += {t[v >> 18], t[(v >> 12) & 63], '=', '='};
  } else if (i + 2 == in.size()) {
    const unsigned v = (static_cast<unsigned char>(in[i]) << 16) | (static_cast<unsigned char>(in[i + 1]) << 8);
    out += {t[v >> 18], t[(v >> 12) & 63], t[(v >> 6) & 63], '='};
  }
  return out;
}

namespace {

/// Reads "t_s,experiment,simulation" style CSVs written by compare.
std::vector<std::vector<double>> readColumns(const fs::path& p) {
  std::istringstream in(readInputFile(p));
  std::string line;
  std::getline(in, line);
  std::vector<std::vector<double>> cols;
  while (std::getline(in, line)) {
    std::stringstream row(line);
    std::string cell;
    std::size_t c = 0;
    while (std::getline(row, cell, ',')) {
      if (cols.size() <= c) cols.resize(c + 1);
      try {
        cols[c].push_back(std::stod(cell));
      } catch (const std::exception&) {
        cols[c].push_back(std::nan(""));
      }
      ++c;
    }
  }
  return cols;
}

/// A compare folder's metrics.json; other metrics.json files (a report's own) are not comparisons.
bool isComparison(const nlohmann::json& j) {
  return j.is_object() && j.contains("schema") && j["schema"].is_string() && j["schema"].get<std::string>() == "mmval-compare/1";
}

using detail::Figure;

/// A file name for figures/: the id with anything but [A-Za-z0-9._-] as '-'.
std::string fileId(const std::string& id) {
  std::string out = id;
  for (char& c : out)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-')) c = '-';
  return out;
}

/// Runs set up as the paper's Table 1 cylinder (unbounded-reference or paper-model
/// acceptance entries), as cylinderDragTable counts them; confined benchmarks are not.
bool paperCylinderSetup(const nlohmann::json& r) {
  for (const auto& m : r["metrics"]) {
    const std::string n = m["name"].get<std::string>();
    if (n.rfind("c_D (", 0) == 0 && (n.find("paper") != std::string::npos || n.find("Dennis") != std::string::npos)) return true;
  }
  return false;
}

}  // namespace

ReportInput collect(const std::vector<fs::path>& dirs) {
  ReportInput input;
  std::function<bool(const fs::path&)> visit = [&](const fs::path& d) {
    bool found = false;
    if (fs::exists(d / "result.json")) {
      input.summary.results.push_back(readJsonFile(d / "result.json"));
      checkResultShape(input.summary.results.back(), d / "result.json");
      input.summary.results.back()["run_dir"] = d.string();
      input.summary.total_wall_seconds += input.summary.results.back()["cost"]["wall_seconds"].get<double>();
      found = true;
    }
    if (fs::exists(d / "metrics.json")) {
      const auto j = readJsonFile(d / "metrics.json");
      if (isComparison(j)) {
        checkCompareShape(j, d / "metrics.json");
        input.comparisons.push_back({d.filename().string(), d, j});
        found = true;
      }
    }
    for (const char* sub : {"runs", "compare"})
      if (fs::is_directory(d / sub)) {
        std::vector<fs::path> children;
        for (const auto& e : fs::directory_iterator(d / sub))
          if (e.is_directory() && e.path().extension() != ".partial") children.push_back(e.path());
        std::sort(children.begin(), children.end());
        for (const auto& c : children) found = visit(c) || found;
      }
    return found;
  };
  for (const auto& d : dirs)
    if (!visit(d)) throw InputError({d.string(), 0, 0, {}}, "no result.json, compare metrics.json or runs/ found", {}, "a folder written by `mmval run`, `mmval compare` or `mmval validate`");
  return input;
}

int writeReport(const ReportInput& input, const fs::path& out) {
  fs::create_directories(out / "figures");
  std::vector<Figure> figures;
  detail::Parts parts;
  const bool plots = gnuplotAvailable();
  auto addPlot = [&](const std::string& id, const std::string& caption, const Plot& p, const std::string& owner = {}) {
    if (!plots) return;
    const std::string file = fileId(id);
    Figure f;
    f.id = id;
    f.caption = caption;
    f.owner = owner;
    f.svg = renderSvg(p);
    f.data = "figures/" + file + ".csv";
    f.data_label = "CSV";
    writeFileAtomic(out / "figures" / (file + ".svg"), f.svg);
    writeFileAtomic(out / f.data, plotCsv(p));
    figures.push_back(std::move(f));
  };
  // A PNG copied into figures/ (deduplicated by source file: a compare-tracks run lists
  // the images its comparison folder also holds).
  std::vector<fs::path> images_seen;
  auto addImage = [&](const std::string& id, const std::string& caption, const fs::path& png, const std::string& owner, std::string data = {},
                      std::string data_label = {}, std::string colour_bar = {}) {
    const fs::path canonical = fs::weakly_canonical(png);
    if (std::find(images_seen.begin(), images_seen.end(), canonical) != images_seen.end()) return;
    images_seen.push_back(canonical);
    Figure f;
    f.id = id;
    f.caption = caption;
    f.owner = owner;
    f.image = fileId(id) + ".png";
    writeFileAtomic(out / "figures" / f.image, readInputFile(png));
    f.data = std::move(data);
    f.data_label = std::move(data_label);
    f.colour_bar = std::move(colour_bar);
    figures.push_back(std::move(f));
  };

  // Speed against error: every run that recorded a resolution ladder.
  {
    Plot p{"Speed against error", "wall time (s)", "relative error", true, true, {}, 640, 420};
    for (const auto& r : input.summary.results) {
      const auto& d = r["details"];
      if (!d.is_object() || !d.contains("ladder")) continue;
      Series s{r["case"]["name"].get<std::string>() + " (" + d.value("solver", std::string("mmval")) + ")", {}, {}, "linespoints"};
      for (const auto& level : d["ladder"])
        if (level.contains("wall_seconds") && level.contains("error") && level["error"].is_number()) {
          s.x.push_back(level["wall_seconds"].get<double>());
          s.y.push_back(std::abs(level["error"].get<double>()));
        }
      if (!s.x.empty()) p.series.push_back(s);
    }
    if (!p.series.empty()) addPlot("speed-vs-error", "Wall time against relative error over each case's resolution ladder (log-log).", p);
  }

  // Drag coefficient against Reynolds number: the runs of the paper's Table 1 set-up (a
  // cylinder with an unbounded-flow reference or the paper's model), with those references.
  // Confined benchmarks (Schaefer-Turek, C_d ~5.6 from wall blockage) are a different
  // problem and stay on their own case pages.
  {
    std::map<std::string, Series> by_label;
    std::vector<std::string> left_out;
    for (const auto& r : input.summary.results) {
      const auto& d = r["details"];
      if (!d.is_object() || !d.contains("Re")) continue;
      if (!paperCylinderSetup(r)) {
        if (std::find(left_out.begin(), left_out.end(), r["case"]["name"].get<std::string>()) == left_out.end()) left_out.push_back(r["case"]["name"].get<std::string>());
        continue;
      }
      const double re = d["Re"].get<double>();
      for (const auto& m : r["metrics"]) {
        const std::string name = m["name"].get<std::string>();
        if (name.rfind("c_D", 0) != 0 || name.rfind("c_D_max", 0) == 0 || !m["value"].is_number()) continue;
        const std::string solver = d.value("solver", std::string("mmval"));
        auto& ours = by_label[solver];
        ours.name = solver;
        ours.style = "points pt 7 ps 1.2";
        if (ours.x.empty() || ours.x.back() != re) {
          ours.x.push_back(re);
          ours.y.push_back(m["value"].get<double>());
        }
        const auto open = name.find(" (");
        if (open != std::string::npos && m["reference"].is_number()) {
          const std::string label = name.substr(open + 2, name.size() - open - 3);
          auto& ref = by_label[label];
          ref.name = label;
          ref.style = "points pt 6 ps 1.5";
          ref.x.push_back(re);
          ref.y.push_back(m["reference"].get<double>());
        }
      }
    }
    // The paper's Table 1 columns at every Re it lists (reference-data/, as in Table 1); they
    // replace the same references taken from the runs' acceptance entries.
    if (!by_label.empty())
      if (const auto t1 = cylinderDragTable(input, findReferenceData(input))) {
        for (std::size_t col = 1; col < t1->header.size() && col <= 6; ++col) {
          Series s{t1->header[col] + " (Table 1)", {}, {}, fmt::format("points pt {} ps 1.2", 2 + 2 * static_cast<int>(col))};  // open symbols
          for (const auto& row : t1->rows) {
            char* end = nullptr;
            const double re = std::strtod(row[0].c_str(), nullptr), cd = std::strtod(row[col].c_str(), &end);
            if (end != row[col].c_str() && std::isfinite(cd) && cd > 0) {
              s.x.push_back(re);
              s.y.push_back(cd);
            }
          }
          if (s.x.empty()) continue;
          by_label.erase(t1->header[col]);
          by_label[s.name] = s;
        }
      }
    Plot p{"Drag coefficient against Reynolds number", "Re", "C_d", true, false, {}, 640, 420};
    for (auto& [label, series] : by_label) p.series.push_back(series);
    if (!p.series.empty() && by_label.begin()->second.x.size() + by_label.rbegin()->second.x.size() >= 2)
      addPlot("cd-vs-re",
              "Drag coefficient against Re of the paper's Table 1 set-up: our runs (filled) and the references their acceptance entries name (open)." +
                  (left_out.empty() ? std::string()
                                    : " Not on these axes (other set-ups, e.g. confined channels whose walls raise C_d): " + fmt::format("{}", fmt::join(left_out, ", ")) +
                                          "; see their case pages."),
              p);
  }

  // Force histories of unsteady runs (forces.csv): c_D and c_L against time, the part in the
  // statistics window in its own colour, the periodic statistics in the caption.
  for (const auto& r : input.summary.results) {
    const auto& d = r["details"];
    if (!d.is_object() || !d.contains("statistics_window_s") || !r.contains("run_dir")) continue;
    const fs::path file = fs::path(r["run_dir"].get<std::string>()) / "forces.csv";
    if (!fs::exists(file)) continue;
    const auto cols = readColumns(file);
    if (cols.size() < 3 || cols[0].empty()) continue;
    const double w0 = d["statistics_window_s"][0].get<double>(), w1 = d["statistics_window_s"][1].get<double>();
    std::array<Series, 4> s{Series{"c_D", {}, {}, "lines"}, Series{"c_L", {}, {}, "lines"}, Series{"c_D, statistics window", {}, {}, "lines"},
                            Series{"c_L, statistics window", {}, {}, "lines"}};
    const std::size_t stride = std::max<std::size_t>(1, cols[0].size() / 3000);  // ~100 points a shedding period at 2D-2's 4700 steps
    for (std::size_t k = 0; k < cols[0].size(); k += stride) {
      const double t = cols[0][k];
      const std::size_t off = (t >= w0 && t <= w1) ? 2 : 0;
      if (off == 0 && t > w1 && !s[0].x.empty() && s[0].x.back() < w0)
        for (std::size_t q = 0; q < 2; ++q) {  // a gap where the window's own series runs
          s[q].x.push_back(w0);
          s[q].y.push_back(std::nan(""));
        }
      for (std::size_t q = 0; q < 2; ++q) {
        s[off + q].x.push_back(t);
        s[off + q].y.push_back(cols[q + 1][k]);
      }
    }
    auto metric = [&](const std::string& name) {
      const auto v = metricValue(r, name);
      return v ? fmt::format("{:.4f}", *v) : std::string("-");
    };
    const std::string name = r["case"]["name"].get<std::string>();
    Plot p{"Force coefficients against time (" + name + ")", "t (s)", "coefficient", false, false, {}, 720, 400};
    // The y range of the statistics window (with a margin): the impulsive start's forces are
    // hundreds of times larger and would flatten the shedding.
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (std::size_t q = 2; q < 4; ++q)
      for (double y : s[q].y)
        if (std::isfinite(y)) lo = std::min(lo, y), hi = std::max(hi, y);
    if (hi > lo) p.yrange = fmt::format("[{}:{}]", lo - 0.25 * (hi - lo), hi + 0.25 * (hi - lo));
    for (auto& x : s)
      if (!x.x.empty()) p.series.push_back(std::move(x));
    addPlot(name + "-forces",
            fmt::format("Drag and lift coefficients against time ({}; y range of the statistics window); statistics window {:.4g} - {:.4g} s ({} shedding periods): c_D max {}, "
                        "c_L max {}, St {}.",
                        name, w0, w1, d.value("shedding_periods", 0), metric("c_D_max"), metric("c_L_max"), metric("St")),
            p, detail::pageKey(r));
  }

  // Comparison figures, their two sides named by what they are (Site.hpp: comparisonNames).
  auto runOf = [&](const ComparisonInput& c) -> nlohmann::json {
    for (const auto& r : input.summary.results)
      if (r.contains("run_dir") && fs::weakly_canonical(r["run_dir"].get<std::string>()) == fs::weakly_canonical(c.dir)) return r;
    return nullptr;
  };
  auto ownerOf = [&](const ComparisonInput& c) {
    const nlohmann::json r = runOf(c);
    return r.is_null() ? "compare-" + c.name : detail::pageKey(r);
  };
  for (const auto& c : input.comparisons) {
    const ComparisonNames names = comparisonNames(runOf(c), input);
    const std::string owner = ownerOf(c);
    auto timePlot = [&](const std::string& file, const std::string& title, const std::string& ylabel, const std::string& id) {
      if (!fs::exists(c.dir / file)) return;
      const auto cols = readColumns(c.dir / file);
      if (cols.size() < 3) return;
      Plot p{title, "t (s)", ylabel, false, false, {{names.reference_short, cols[0], cols[1], "linespoints"}, {names.candidate_short, cols[0], cols[2], "linespoints"}}};
      addPlot(c.name + "-" + id, title + " (" + names.kind + ": " + names.reference + " against " + names.candidate + ")", p, owner);
    };
    timePlot("mean_speed_time_um_per_s.csv", "Mean particle speed against time", "speed (um/s)", "speed");
    timePlot("sigma_x_time_um.csv", "Dispersion sigma_x against time", "sigma_x (um)", "sigma-x");
    timePlot("sigma_y_time_um.csv", "Dispersion sigma_y against time", "sigma_y (um)", "sigma-y");
    if (fs::exists(c.dir / "speed_histogram.csv")) {
      const auto cols = readColumns(c.dir / "speed_histogram.csv");
      if (cols.size() >= 3)
        addPlot(c.name + "-histogram", "Speed distributions per step (" + names.kind + ": " + names.reference + " against " + names.candidate + ")",
                Plot{"Speed distribution", "speed (um/s)", "fraction of steps", false, false,
                     {{names.reference_short, cols[0], cols[1], "steps"}, {names.candidate_short, cols[0], cols[2], "steps"}}},
                owner);
    }
    if (fs::exists(c.dir / "streamlines.png"))
      addImage(c.name + "-streamlines",
               "Streamline occupancy: " + names.reference + " | " + names.candidate + " | overlay (magenta: the first, green: the second, white: both)", c.dir / "streamlines.png",
               owner);
    if (fs::exists(c.dir / "regions.png"))
      addImage(c.name + "-regions", "Pore bodies (blue) and throats (orange) of the geometry mask", c.dir / "regions.png", owner,
               fs::exists(c.dir / "region_speeds.csv") ? detail::relativeLink(c.dir / "region_speeds.csv", out) : std::string(),
               "region_speeds.csv (CSV)");
    if (fs::exists(c.dir / "registration.png"))
      addImage(c.name + "-registration", "Registration check: the frame of " + names.reference + " with the mask's grain outlines (green) carried by the fitted motion",
               c.dir / "registration.png", owner);
  }
  const fs::path refdir = findReferenceData(input);
  nlohmann::json extra_metrics = nlohmann::json::array();

  const PermeabilityFigure permeability = permeabilityFigure(input, refdir);
  if (permeability.plot)
    addPlot("permeability-time", "Normalised permeability k/k0 against time of every run that wrote permeability.csv; filled diamonds with labels: the paper's Table 3 reductions.",
            *permeability.plot);
  for (const auto& m : permeability.metrics) extra_metrics.push_back(m);
  const auto& reduction_rows = permeability.rows;
  if (const auto p = retentionFigure(input, refdir))
    addPlot("retention-time", "Retained fraction against time: every run's retention.csv (retained / injected; for a tracked video, injected counts the tracks that entered the field of view) and track comparisons (retained / mobile seen so far; the tracked side of a pipeline check is a rendered simulation, not an experiment).", *p);

  // The paper's tables from the runs present.
  std::vector<Table> tables;
  if (auto t = cylinderDragTable(input, refdir)) tables.push_back(*t);
  if (auto t = chipTable(input, refdir)) tables.push_back(*t);
  if (auto t = engineComparisonTable(input)) tables.push_back(*t);
  if (!reduction_rows.empty()) {
    Table t;
    t.id = "table3";
    t.title = "Permeability reduction (the paper's Table 3 cases)";
    t.note = "Runs that wrote permeability.csv; the paper's value when the run name names a Table 3 case (case-I ... case-V).";
    t.header = {"run", "Table 3 case", "t end (s)", "k/k0 at end", "reduction", "paper", "difference", "first 10 % loss (s)", "clogged (s)"};
    t.rows = reduction_rows;
    tables.push_back(t);
  }
  if (auto t = table3TrendsTable(input, refdir)) tables.push_back(*t);
  for (const auto& c : input.comparisons) {
    if (!c.metrics.contains("regions")) continue;
    const auto& g = c.metrics["regions"];
    const ComparisonNames names = comparisonNames(runOf(c), input);
    Table t;
    t.id = "regions-" + c.name;
    t.title = "Mean speed per region";
    t.note = g.value("rule", "") + " Columns: " + names.reference + " (first) and " + names.candidate + " (second).";
    t.header = {"region", "tracked: " + names.reference + " (um/s)", names.candidate + " (um/s)", "relative difference", "steps (first)", "steps (second)"};
    auto cell = [](const nlohmann::json& v) { return v.is_number() ? fmt::format("{:.4g}", v.get<double>()) : std::string("-"); };
    for (const auto& [label, key, steps, diff] : std::vector<std::array<std::string, 4>>{
             {"pore bodies", "pore_body_mean_speed_um_per_s", "pore_body_steps", "speed_pore_bodies_relative_difference"},
             {"throats", "throat_mean_speed_um_per_s", "throat_steps", "speed_throats_relative_difference"}})
      t.rows.push_back({label, cell(g["experiment"][key]), cell(g["simulation"][key]),
                        g.contains(diff) ? fmt::format("{:+.1f} %", 100 * g[diff].get<double>()) : "-", cell(g["experiment"][steps]), cell(g["simulation"][steps])});
    parts.case_tables.emplace_back(ownerOf(c), t);
  }
  std::vector<std::string> alignments;
  for (const auto& c : input.comparisons) {
    if (!c.metrics.contains("alignment")) continue;
    const auto& a = c.metrics["alignment"];
    if (a.contains("dx_px"))
      alignments.push_back(fmt::format("{}: frame registered to the mask ({}): dx {:.3f} px ({:.3g} um), dy {:.3f} px ({:.3g} um), rotation {:.4f} deg, scale {:g}; "
                                       "ECC correlation {:.4f}, RMS intensity residual {:.4f}, overlap {:.0f} %",
                                       c.name, a.value("method", ""), a["dx_px"].get<double>(), a.value("dx_um", 0.0), a["dy_px"].get<double>(), a.value("dy_um", 0.0),
                                       a["rotation_deg"].get<double>(), a.value("scale", 1.0), a["ecc_correlation"].get<double>(), a["rms_residual"].get<double>(),
                                       100 * a.value("overlap_fraction", 0.0)));
    else
      alignments.push_back(c.name + ": " + a.dump());
  }

  // Physics checks: each run's measured values against its theory, on its case page, the
  // figure linked to the run's own CSV it is drawn from.
  for (const auto& r : input.summary.results) {
    if (!plots) break;
    for (const CheckFigure& cf : physicsCheckFigures(r, refdir)) {
      Figure f;
      f.id = detail::pageKey(r) + "-" + cf.id;
      f.caption = cf.caption;
      f.owner = detail::pageKey(r);
      f.svg = renderSvg(cf.plot);
      f.data = detail::relativeLink(cf.data, out);
      f.data_label = cf.data.filename().string() + " (CSV)";
      writeFileAtomic(out / "figures" / (fileId(f.id) + ".svg"), f.svg);
      figures.push_back(std::move(f));
    }
  }

  // Images produced by runs (PNG files listed in result.json); speed fields get a colour bar
  // from 0 to the largest cell speed of the run's fields.vtr (simulate scales them so).
  for (const auto& r : input.summary.results) {
    if (!r.contains("run_dir")) continue;
    const fs::path run_dir = r["run_dir"].get<std::string>();
    const std::string case_name = detail::pageKey(r);
    for (const auto& f : r.value("files", nlohmann::json::array())) {
      const std::string name = f.get<std::string>();
      if (name.size() <= 4 || name.substr(name.size() - 4) != ".png") continue;
      const fs::path p = run_dir / name;
      if (!fs::exists(p)) continue;
      std::string data, data_label, bar;
      const fs::path vtr = run_dir / "fields.vtr";
      const std::string file_name = fs::path(name).filename().string();
      if (file_name == "speed.png" || (file_name.rfind("fields", 0) == 0 && file_name.find("speed") != std::string::npos)) {
        const bool plane = name.find("middepth") != std::string::npos;
        const double vmax = plane ? std::nan("") : maxSpeedOfVtr(vtr);
        bar = colourBarHtml(0.0, vmax, "m/s", plane ? "speed |u| on the mid-depth plane (range of the plane)" : "speed |u|");
        if (fs::exists(vtr)) {
          data = detail::relativeLink(vtr, out);
          data_label = "fields (.vtr)";
        }
      }
      // Tracking images: the CSV they are drawn from sits beside them.
      for (const char* csv : {file_name == "speed_map.png" ? "velocities.csv" : "tracks.csv"})
        if (data.empty() && fs::exists(p.parent_path() / csv)) {
          data = detail::relativeLink(p.parent_path() / csv, out);
          data_label = std::string(csv) + " (CSV)";
        }
      addImage(case_name + "-" + fs::path(name).stem().string(), name + (bar.empty() ? std::string() : " (speed field, viridis from 0 to the largest cell speed)"), p,
               case_name, data, data_label, bar);
    }
  }
  parts.figures = figures;
  parts.tables = tables;
  parts.alignments = alignments;
  parts.plots = plots;

  // metrics.json: runs and comparisons together.
  nlohmann::json metrics = input.summary.metricsJson();
  for (const auto& c : input.comparisons)
    for (auto m : c.metrics["metrics"]) {
      m["case"] = "compare:" + c.name;
      metrics["metrics"].push_back(m);
      if (m["pass"].is_boolean() && !m["pass"].get<bool>()) metrics["all_pass"] = false;
    }
  for (const auto& m : extra_metrics) metrics["metrics"].push_back(m);
  metrics["tables"] = nlohmann::json::array();
  for (const auto& t : tables) metrics["tables"].push_back({{"id", t.id}, {"title", t.title}, {"header", t.header}, {"rows", t.rows}});
  for (const auto& c : input.comparisons) {
    if (c.metrics.contains("alignment")) metrics["alignment"][c.name] = c.metrics["alignment"];
    if (c.metrics.contains("regions")) metrics["regions"][c.name] = c.metrics["regions"];
  }
  writeFileAtomic(out / "metrics.json", metrics.dump(2) + "\n");

  // Markdown.
  std::string md = input.summary.markdown();
  for (const auto& c : input.comparisons) {
    const ComparisonNames names = comparisonNames(runOf(c), input);
    md += fmt::format("\n## {}: {}\n\n{}\n\nvalue: {}; reference: {}.\n\n| metric | value | reference | error | tolerance | result |\n|---|---|---|---|---|---|\n", names.kind,
                      c.name, names.explanation, names.candidate, names.reference);
    for (const auto& m : c.metrics["metrics"])
      md += fmt::format("| {} | {:.4g} {} | {} {} | {} | {} | {} |\n", m["name"].get<std::string>(), m["value"].is_number() ? m["value"].get<double>() : std::nan(""),
                        m.value("unit", ""), referenceText(m), m["reference"].is_null() ? "" : m.value("unit", ""), errorText(m),
                        m["tolerance"].is_null() ? "-" : m["tolerance"].get<std::string>(), m["pass"].is_null() ? "info" : (m["pass"].get<bool>() ? "pass" : "FAIL"));
  }
  for (const auto& t : tables) md += t.markdown();
  if (!alignments.empty()) {
    md += "\n## Alignment of tracked frames and simulation\n\n";
    for (const auto& a : alignments) md += "- " + a + "\n";
  }
  md += "\n## Figures\n\n";
  for (const auto& f : figures)
    md += f.svg.empty() ? fmt::format("- {} (`figures/{}`)\n", f.caption, f.image) : fmt::format("- {} (`figures/{}.svg`, data `{}`)\n", f.caption, fileId(f.id), f.data);
  writeFileAtomic(out / "report.md", md);

  // HTML: the summary, the cross-case page and one page per case.
  detail::writePages(input, parts, out);
  return static_cast<int>(figures.size());
}

std::string diffMetricFiles(const fs::path& before, const fs::path& after) {
  const nlohmann::json a = readJsonFile(before), b = readJsonFile(after);
  checkMetricsListShape(a, before);
  checkMetricsListShape(b, after);
  return diffMetrics(a, b);
}

std::string diffMetrics(const nlohmann::json& a, const nlohmann::json& b) {
  checkMetricsListShape(a, "(first metrics document)");
  checkMetricsListShape(b, "(second metrics document)");
  // compare's metrics.json and result.json name no case per metric.
  auto keyOf = [](const nlohmann::json& m) { return m.value("case", std::string()) + "/" + m["name"].get<std::string>(); };
  std::map<std::string, nlohmann::json> before;
  for (const auto& m : a["metrics"]) before[keyOf(m)] = m;
  std::string out = "| case/metric | before | after | change | tolerance | before result | after result |\n|---|---|---|---|---|---|---|\n";
  int n = 0;
  for (const auto& m : b["metrics"]) {
    const std::string key = keyOf(m);
    auto it = before.find(key);
    auto result = [](const nlohmann::json& x) { return x["pass"].is_null() ? std::string("info") : (x["pass"].get<bool>() ? "pass" : "FAIL"); };
    if (it == before.end()) {
      out += fmt::format("| {} | (new) | {} | | | | {} |\n", key, m["value"].dump(), result(m));
      ++n;
      continue;
    }
    const auto& o = it->second;
    if (!m["value"].is_number() || !o["value"].is_number()) continue;
    const double va = o["value"].get<double>(), vb = m["value"].get<double>();
    const double rel = va != 0 ? std::abs(vb - va) / std::abs(va) : std::abs(vb);
    // "Beyond tolerance": the change is larger than the metric's own tolerance (1e-9 for informational ones).
    double tol = 1e-9;
    const std::string t = m["tolerance"].is_string() ? m["tolerance"].get<std::string>() : "";
    if (!t.empty() && t.back() == '%') tol = std::strtod(t.c_str(), nullptr) / 100;
    if (rel > tol || result(o) != result(m)) {
      out += fmt::format("| {} | {:.6g} | {:.6g} | {:+.3g} % | {} | {} | {} |\n", key, va, vb, 100 * (vb - va) / (va != 0 ? va : 1), t.empty() ? "-" : t, result(o), result(m));
      ++n;
    }
  }
  return n == 0 ? std::string("No metric changed beyond its tolerance.\n") : out;
}

}  // namespace mmval::reports
