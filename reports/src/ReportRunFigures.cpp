// writeReport's figure stages of single runs and comparisons: comparison
// plots and images, the paper's permeability and retention figures, physics
// checks, and the images runs wrote.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>

#include <fmt/format.h>

#include "mmval/reports/PaperFigures.hpp"
#include "mmval/reports/PhysicsFigures.hpp"
#include "mmval/reports/Site.hpp"
#include "ReportStages.hpp"

namespace fs = std::filesystem;

namespace mmval::reports::detail {

namespace {

/// One comparison's figures; `names` says what its two sides are.
void comparisonFigure(const ComparisonInput& c, const ComparisonNames& names, const std::string& owner, FigureSink& sink) {
  auto timePlot = [&](const std::string& file, const std::string& title, const std::string& ylabel, const std::string& id) {
    if (!fs::exists(c.dir / file)) return;
    const auto cols = readColumns(c.dir / file);
    if (cols.size() < 3) return;
    Plot p{title, "t (s)", ylabel, false, false, {{names.reference_short, cols[0], cols[1], "linespoints"}, {names.candidate_short, cols[0], cols[2], "linespoints"}}};
    sink.addPlot(c.name + "-" + id, title + " (" + names.kind + ": " + names.reference + " against " + names.candidate + ")", p, owner);
  };
  timePlot("mean_speed_time_um_per_s.csv", "Mean particle speed against time", "speed (um/s)", "speed");
  timePlot("sigma_x_time_um.csv", "Dispersion sigma_x against time", "sigma_x (um)", "sigma-x");
  timePlot("sigma_y_time_um.csv", "Dispersion sigma_y against time", "sigma_y (um)", "sigma-y");
  if (fs::exists(c.dir / "speed_histogram.csv")) {
    const auto cols = readColumns(c.dir / "speed_histogram.csv");
    if (cols.size() >= 3)
      sink.addPlot(c.name + "-histogram", "Speed distributions per step (" + names.kind + ": " + names.reference + " against " + names.candidate + ")",
                   Plot{"Speed distribution", "speed (um/s)", "fraction of steps", false, false,
                        {{names.reference_short, cols[0], cols[1], "steps"}, {names.candidate_short, cols[0], cols[2], "steps"}}},
                   owner);
  }
  if (fs::exists(c.dir / "streamlines.png"))
    sink.addImage(c.name + "-streamlines",
                  "Streamline occupancy: " + names.reference + " | " + names.candidate + " | overlay (magenta: the first, green: the second, white: both)",
                  c.dir / "streamlines.png", owner);
  if (fs::exists(c.dir / "regions.png"))
    sink.addImage(c.name + "-regions", "Pore bodies (blue) and throats (orange) of the geometry mask", c.dir / "regions.png", owner,
                  fs::exists(c.dir / "region_speeds.csv") ? relativeLink(c.dir / "region_speeds.csv", sink.out()) : std::string(),
                  "region_speeds.csv (CSV)");
  if (fs::exists(c.dir / "registration.png"))
    sink.addImage(c.name + "-registration",
                  "Registration check: the frame of " + names.reference + " with the mask's grain outlines (green) carried by the fitted motion",
                  c.dir / "registration.png", owner);
}

/// A run's image: what it shows, the file behind it, its label and (speed fields) a colour bar.
struct ImageData {
  std::string caption, data, label, bar;
};

/// What the images the runs write show (simulate's field pictures, the tracker's and the micromodel scene's pictures).
std::string imageCaption(const std::string& file_name) {
  if (file_name == "streamlines.png") return "tracks drawn over the background image, one colour per track";
  if (file_name == "velocity_overlay.png") return "per-frame steps drawn where they are, coloured by speed (colour bar in the image, um/s)";
  if (file_name == "speed_map.png") return "mean speed of the steps in each bin of the view, coloured by speed (colour bar in the image, um/s; grey: no step)";
  if (file_name == "deposits.png")
    return "the chip's grains (grey), particle paths (blue: moving or left; orange: ended deposited; at most 600) and every retained particle "
           "(red) where it stopped";
  return {};
}

ImageData imageData(const fs::path& run_dir, const std::string& name, const fs::path& out) {
  ImageData d;
  const fs::path p = run_dir / name;
  const std::string file_name = fs::path(name).filename().string();
  d.caption = imageCaption(file_name);
  // Speed fields: a colour bar from 0 to the largest cell speed simulate scaled the picture to:
  // that of fields.vtr for the plane pictures, that of the middle cell layer of fields-3d.vtr
  // for the 3D solve's mid-depth picture.
  if (file_name == "speed.png" || (file_name.rfind("fields", 0) == 0 && file_name.find("speed") != std::string::npos)) {
    const bool mid_depth = file_name.find("middepth") != std::string::npos;
    const fs::path vtr = run_dir / (mid_depth ? "fields-3d.vtr" : "fields.vtr");
    const double vmax = mid_depth ? maxSpeedOnMidDepthPlane(vtr) : maxSpeedOfVtr(vtr);
    d.bar = colourBarHtml(0.0, vmax, "m/s", mid_depth ? "speed |u| on the mid-depth plane" : "speed |u|");
    d.caption = mid_depth ? "speed on the mid-depth plane of the 3D Stokes solve, viridis from 0 to the plane's largest cell speed"
                          : "speed field, viridis from 0 to the largest cell speed";
    if (fs::exists(vtr)) {
      d.data = relativeLink(vtr, out);
      d.label = mid_depth ? "fields-3d (.vtr)" : "fields (.vtr)";
    }
  }
  // Tracking images: the CSV they are drawn from sits beside them.
  const char* csv = file_name == "streamlines.png" ? "tracks.csv" : file_name == "deposits.png" ? "trajectories.csv" : "velocities.csv";
  if (d.data.empty() && !d.caption.empty() && fs::exists(p.parent_path() / csv)) {
    d.data = relativeLink(p.parent_path() / csv, out);
    d.label = std::string(csv) + " (CSV)";
  }
  return d;
}

}  // namespace

void comparisonFigures(const ReportInput& input, FigureSink& sink) {
  for (const auto& c : input.comparisons) comparisonFigure(c, comparisonNames(runOf(input, c), input), ownerOf(input, c), sink);
}

PaperFigureResults paperFigures(const ReportInput& input, const fs::path& reference_dir, FigureSink& sink) {
  PaperFigureResults results;
  const PermeabilityFigure permeability = permeabilityFigure(input, reference_dir);
  if (permeability.plot)
    sink.addPlot("permeability-time",
                 "Normalised permeability k/k0 against time of every run that wrote permeability.csv" +
                     std::string(permeability.paper_points > 0
                                     ? "; filled diamonds with labels: the paper's Table 3 reductions of the runs that reproduce a Table 3 case."
                                     : "; no run reproduces a case of the paper's Table 3 (analysis.table3_case), so none of its reductions is drawn."),
                 *permeability.plot);
  for (const auto& m : permeability.metrics) results.metrics.push_back(m);
  results.reduction_rows = permeability.rows;
  if (const auto p = retentionFigure(input, reference_dir))
    sink.addPlot("retention-time",
                 "Retained fraction against time: every run's retention.csv (retained / injected; for a tracked video, injected counts the tracks that entered "
                 "the field of view) and track comparisons (retained / mobile seen so far; the tracked side of a pipeline check is a rendered simulation, not an "
                 "experiment).",
                 *p);
  return results;
}

void physicsFigures(const ReportInput& input, const fs::path& reference_dir, FigureSink& sink) {
  if (!sink.plots()) return;
  for (const auto& r : input.summary.results)
    for (const CheckFigure& cf : physicsCheckFigures(r, reference_dir)) {
      Figure f;
      f.id = pageKey(r) + "-" + cf.id;
      f.caption = cf.caption;
      f.owner = pageKey(r);
      f.svg = renderSvg(cf.plot);
      f.data = relativeLink(cf.data, sink.out());
      f.data_label = cf.data.filename().string() + " (CSV)";
      sink.addRendered(std::move(f));
    }
}

void sweepFigures(const ReportInput& input, FigureSink& sink) {
  if (!sink.plots()) return;
  for (const auto& sw : input.sweeps) {
    const nlohmann::json& doc = sw.sweep;
    if (doc["axes"].empty() || doc["groups"].empty()) continue;
    const nlohmann::json d = doc.value("discretisation", nlohmann::json::object());
    const auto keyOf = [&](const char* axis) { return d.contains(axis) && d[axis].is_object() ? d[axis]["key"].get<std::string>() : std::string(); };
    const std::string grid = keyOf("grid"), step = keyOf("step");
    const std::string x_key = grid.empty() ? doc["axes"][0]["key"].get<std::string>() : grid;
    // x: the axis value as a number; an axis of words is drawn by the index of its value.
    std::vector<std::string> x_values;
    for (const auto& v : doc["axes"])
      if (v["key"] == x_key)
        for (const auto& value : v["values"]) {
          std::string text = value.get<std::string>();
          if (text.size() >= 2 && text.front() == '"' && text.back() == '"') text = text.substr(1, text.size() - 2);
          x_values.push_back(text);
        }
    bool numeric = true;
    double lo = INFINITY, hi = -INFINITY;
    for (const auto& v : x_values) {
      char* end = nullptr;
      const double x = std::strtod(v.c_str(), &end);
      numeric = numeric && end != v.c_str() && x > 0;
      lo = std::min(lo, x);
      hi = std::max(hi, x);
    }
    const auto xOf = [&](const std::string& v) {
      const auto at = std::find(x_values.begin(), x_values.end(), v);
      return numeric ? std::strtod(v.c_str(), nullptr) : static_cast<double>(at - x_values.begin());
    };
    std::vector<std::string> metrics;
    for (const auto& m : doc.value("metrics_shown", nlohmann::json::array())) metrics.push_back(m.get<std::string>());
    if (metrics.empty())  // every metric whose mean varies over the settings
      for (const auto& [name, stats] : doc["groups"][0]["metrics"].items()) {
        double a = INFINITY, b = -INFINITY;
        for (const auto& g : doc["groups"])
          if (g["metrics"].contains(name) && g["metrics"][name]["mean"].is_number()) {
            a = std::min(a, g["metrics"][name]["mean"].get<double>());
            b = std::max(b, g["metrics"][name]["mean"].get<double>());
          }
        if (b > a) metrics.push_back(name);
      }
    for (const auto& metric : metrics) {
      std::map<std::string, Series> lines;
      for (const auto& g : doc["groups"]) {
        if (!g["metrics"].contains(metric) || !g["metrics"][metric]["mean"].is_number()) continue;
        std::string label;
        for (const auto& [k, v] : g["setting"].items())
          if (k != x_key) label += (label.empty() ? "" : ", ") + k + "=" + v.get<std::string>();
        Series& line = lines[label];
        line.name = label.empty() ? metric : label;
        line.style = "yerrorlines";
        line.x.push_back(xOf(g["setting"][x_key].get<std::string>()));
        line.y.push_back(g["metrics"][metric]["mean"].get<double>());
        line.yerr.push_back(g["metrics"][metric]["se"].is_number() ? g["metrics"][metric]["se"].get<double>() : 0.0);
      }
      if (lines.empty()) continue;
      std::string unit;
      if (doc.contains("uncertainty") && doc["uncertainty"].contains(metric)) unit = doc["uncertainty"][metric]["unit"].get<std::string>();
      Plot p;
      p.title = sw.name + ": " + metric + " (mean +- standard error over seeds)";
      p.xlabel = x_key + (grid.empty() ? "" : " (grid; finer: " + d["grid"].value("finer", std::string("?")) + ")");
      if (!numeric) {
        p.xlabel += " (";
        for (std::size_t i = 0; i < x_values.size(); ++i) p.xlabel += (i ? ", " : "") + std::to_string(i) + ": " + x_values[i];
        p.xlabel += ")";
      }
      p.ylabel = metric + (unit.empty() || unit == "1" ? "" : " (" + unit + ")");
      // gnuplot's axis labels are enhanced text: "_" would start a subscript.
      for (std::string* label : {&p.xlabel, &p.ylabel})
        for (std::size_t at = 0; (at = label->find('_', at)) != std::string::npos; at += 2) label->insert(at, "\\");
      p.logx = numeric && hi / lo >= 10;
      // The lines are shifted sideways (up to 1.5 % of the axis) so that their error bars do not hide each other.
      const double span = numeric ? (p.logx ? std::log(hi / lo) : hi - lo) : static_cast<double>(x_values.size() - 1);
      const double count = static_cast<double>(lines.size());
      double k = 0;
      for (auto& [label, line] : lines) {
        const double shift = count > 1 ? (k++ - (count - 1) / 2) / (count - 1) * 0.03 * span : 0.0;
        for (double& x : line.x) x = p.logx ? x * std::exp(shift) : x + shift;
        p.series.push_back(std::move(line));
      }
      sink.addPlot(sweepPageKey(sw) + "-" + metric,
                   metric + " against " + x_key + (step.empty() ? "" : ", one line per " + step + " value") +
                       " (and per setting of the other axes), the lines shifted sideways by up to 1.5 % of the axis so that their error bars can be told apart; "
                       "error bars: standard error of the mean over the seeds. Sweep folder " + sw.name + ".",
                   p, sweepPageKey(sw));
    }
  }
}

void runImages(const ReportInput& input, FigureSink& sink) {
  for (const auto& r : input.summary.results) {
    if (!r.contains("run_dir")) continue;
    const fs::path run_dir = r["run_dir"].get<std::string>();
    const std::string case_name = pageKey(r);
    for (const auto& f : r.value("files", nlohmann::json::array())) {
      const std::string name = f.get<std::string>();
      if (name.size() <= 4 || name.substr(name.size() - 4) != ".png") continue;
      const fs::path p = run_dir / name;
      if (!fs::exists(p)) continue;
      ImageData d = imageData(run_dir, name, sink.out());
      const std::string caption = name + (d.caption.empty() ? std::string() : " (" + d.caption + ")");
      sink.addImage(case_name + "-" + fs::path(name).stem().string(), caption, p, case_name, std::move(d.data), std::move(d.label), std::move(d.bar));
    }
  }
}

}  // namespace mmval::reports::detail
