#include "mmval/reports/Report.hpp"

#include <algorithm>
#include <array>
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
#include "mmval/reports/Tables.hpp"

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

struct Figure {
  std::string id, caption, svg, png_base64;
};

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
  const bool plots = gnuplotAvailable();
  auto addPlot = [&](const std::string& id, const std::string& caption, const Plot& p) {
    if (!plots) return;
    Figure f{id, caption, renderSvg(p), {}};
    writeFileAtomic(out / "figures" / (id + ".svg"), f.svg);
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

  // Drag coefficient against Reynolds number: every cylinder run, with the references its
  // acceptance entries name (the paper's Table 1 as a figure).
  {
    std::map<std::string, Series> by_label;
    for (const auto& r : input.summary.results) {
      const auto& d = r["details"];
      if (!d.is_object() || !d.contains("Re")) continue;
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
    Plot p{"Drag coefficient against Reynolds number", "Re", "C_d", true, false, {}, 640, 420};
    for (auto& [label, series] : by_label) p.series.push_back(series);
    if (!p.series.empty() && by_label.begin()->second.x.size() + by_label.rbegin()->second.x.size() >= 2)
      addPlot("cd-vs-re", "Drag coefficient against Re: our runs (filled) and their references (open).", p);
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
            p);
  }

  // Experiment vs simulation figures.
  for (const auto& c : input.comparisons) {
    auto timePlot = [&](const std::string& file, const std::string& title, const std::string& ylabel, const std::string& id) {
      if (!fs::exists(c.dir / file)) return;
      const auto cols = readColumns(c.dir / file);
      if (cols.size() < 3) return;
      Plot p{title, "t (s)", ylabel, false, false, {{"experiment", cols[0], cols[1], "linespoints"}, {"simulation", cols[0], cols[2], "linespoints"}}};
      addPlot(c.name + "-" + id, title + " (" + c.name + ")", p);
    };
    timePlot("mean_speed_time_um_per_s.csv", "Mean particle speed against time", "speed (um/s)", "speed");
    timePlot("sigma_x_time_um.csv", "Dispersion sigma_x against time", "sigma_x (um)", "sigma-x");
    timePlot("sigma_y_time_um.csv", "Dispersion sigma_y against time", "sigma_y (um)", "sigma-y");
    if (fs::exists(c.dir / "speed_histogram.csv")) {
      const auto cols = readColumns(c.dir / "speed_histogram.csv");
      if (cols.size() >= 3)
        addPlot(c.name + "-histogram", "Speed distributions (" + c.name + ")",
                Plot{"Speed distribution", "speed (um/s)", "fraction of steps", false, false,
                     {{"experiment", cols[0], cols[1], "steps"}, {"simulation", cols[0], cols[2], "steps"}}});
    }
    if (fs::exists(c.dir / "streamlines.png"))
      figures.push_back({c.name + "-streamlines", "Streamline occupancy: experiment | simulation | overlay (magenta experiment, green simulation, white both) (" + c.name + ")", {}, base64(readInputFile(c.dir / "streamlines.png"))});
  }
  const fs::path refdir = findReferenceData(input);
  nlohmann::json extra_metrics = nlohmann::json::array();

  const PermeabilityFigure permeability = permeabilityFigure(input, refdir);
  if (permeability.plot)
    addPlot("permeability-time", "Normalised permeability k/k0 against time of every run that wrote permeability.csv; diamonds: the paper's Table 3 reductions.",
            *permeability.plot);
  for (const auto& m : permeability.metrics) extra_metrics.push_back(m);
  const auto& reduction_rows = permeability.rows;
  if (const auto p = retentionFigure(input, refdir))
    addPlot("retention-time", "Retained fraction against time: simulations (retained / injected) and experiment vs simulation comparisons (retained / mobile seen so far).", *p);

  // Per comparison: pore bodies and throats of the geometry.
  for (const auto& c : input.comparisons) {
    if (fs::exists(c.dir / "regions.png"))
      figures.push_back({c.name + "-regions", "Pore bodies (blue) and throats (orange) of the geometry mask (" + c.name + ")", {}, base64(readInputFile(c.dir / "regions.png"))});
    if (fs::exists(c.dir / "registration.png"))
      figures.push_back({c.name + "-registration", "Registration check: the experiment's frame with the mask's grain outlines (green) carried by the fitted motion (" + c.name + ")", {},
                         base64(readInputFile(c.dir / "registration.png"))});
  }

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
    Table t;
    t.id = "regions-" + c.name;
    t.title = "Mean speed per region: " + c.name;
    t.note = g.value("rule", "");
    t.header = {"region", "experiment (um/s)", "simulation (um/s)", "relative difference", "experiment steps", "simulation steps"};
    auto cell = [](const nlohmann::json& v) { return v.is_number() ? fmt::format("{:.4g}", v.get<double>()) : std::string("-"); };
    for (const auto& [label, key, steps, diff] : std::vector<std::array<std::string, 4>>{
             {"pore bodies", "pore_body_mean_speed_um_per_s", "pore_body_steps", "speed_pore_bodies_relative_difference"},
             {"throats", "throat_mean_speed_um_per_s", "throat_steps", "speed_throats_relative_difference"}})
      t.rows.push_back({label, cell(g["experiment"][key]), cell(g["simulation"][key]),
                        g.contains(diff) ? fmt::format("{:+.1f} %", 100 * g[diff].get<double>()) : "-", cell(g["experiment"][steps]), cell(g["simulation"][steps])});
    tables.push_back(t);
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

  // Images produced by runs (PNG files listed in result.json).
  for (const auto& r : input.summary.results)
    for (const auto& f : r.value("files", nlohmann::json::array())) {
      const std::string name = f.get<std::string>();
      if (name.size() > 4 && name.substr(name.size() - 4) == ".png" && r.contains("run_dir")) {
        const fs::path p = fs::path(r["run_dir"].get<std::string>()) / name;
        if (fs::exists(p)) figures.push_back({r["case"]["name"].get<std::string>() + "-" + name, r["case"]["name"].get<std::string>() + ": " + name, {}, base64(readInputFile(p))});
      }
    }

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
    md += fmt::format("\n## Experiment vs simulation: {}\n\n| metric | simulation | experiment | error | tolerance | result |\n|---|---|---|---|---|---|\n", c.name);
    for (const auto& m : c.metrics["metrics"])
      md += fmt::format("| {} | {:.4g} {} | {} | {} | {} | {} |\n", m["name"].get<std::string>(), m["value"].is_number() ? m["value"].get<double>() : std::nan(""),
                        m.value("unit", ""), referenceText(m), errorText(m), m["tolerance"].is_null() ? "-" : m["tolerance"].get<std::string>(),
                        m["pass"].is_null() ? "info" : (m["pass"].get<bool>() ? "pass" : "FAIL"));
  }
  for (const auto& t : tables) md += t.markdown();
  if (!alignments.empty()) {
    md += "\n## Alignment of experiment and simulation\n\n";
    for (const auto& a : alignments) md += "- " + a + "\n";
  }
  md += "\n## Figures\n\n";
  for (const auto& f : figures)
    md += f.svg.empty() ? fmt::format("- {} (PNG, inline in index.html)\n", f.caption) : fmt::format("- {} (`figures/{}.svg`)\n", f.caption, f.id);
  writeFileAtomic(out / "report.md", md);

  // HTML: the summary page with figures appended before the closing tags.
  std::string html = input.summary.html();
  std::string extra;
  for (const auto& c : input.comparisons) {
    extra += fmt::format("<h2>Experiment vs simulation: {}</h2>\n<table class=\"compare\"><tr><th>metric</th><th>simulation</th><th>experiment</th><th>error</th><th>tolerance</th><th>result</th></tr>\n", htmlEscape(c.name));
    for (const auto& m : c.metrics["metrics"]) {
      const std::string pass = m["pass"].is_null() ? "info" : (m["pass"].get<bool>() ? "pass" : "FAIL");
      extra += fmt::format("<tr class=\"{}\"><td>{}</td><td>{:.4g} {}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>\n", pass,
                           htmlEscape(m["name"].get<std::string>()), m["value"].is_number() ? m["value"].get<double>() : std::nan(""),
                           htmlEscape(m.value("unit", "")), htmlEscape(referenceText(m)), htmlEscape(errorText(m)),
                           htmlEscape(m["tolerance"].is_null() ? "-" : m["tolerance"].get<std::string>()), pass);
    }
    extra += "</table>\n";
  }
  for (const auto& t : tables) extra += t.html();
  if (!alignments.empty()) {
    extra += "<h2>Alignment of experiment and simulation</h2>\n<ul id=\"alignment\">\n";
    for (const auto& a : alignments) extra += "<li>" + htmlEscape(a) + "</li>\n";
    extra += "</ul>\n";
  }
  if (!figures.empty()) extra += "<h2>Figures</h2>\n";
  for (const auto& f : figures) {
    extra += fmt::format("<figure id=\"fig-{}\">\n", htmlEscape(f.id));
    if (!f.svg.empty())
      extra += f.svg;
    else
      extra += fmt::format("<img alt=\"{}\" style=\"max-width:100%;image-rendering:pixelated\" src=\"data:image/png;base64,{}\">", htmlEscape(f.caption), f.png_base64);
    extra += fmt::format("\n<figcaption>{}</figcaption></figure>\n", htmlEscape(f.caption));
  }
  if (!plots) extra += "<p><b>gnuplot was not found: plots were left out.</b></p>\n";
  // A check the headless-browser test reads: how many images decoded.
  extra += "<p id=\"image-status\"></p>\n<script>window.addEventListener('load',function(){var im=document.images,ok=0;"
           "for(var i=0;i<im.length;i++){if(im[i].complete&&im[i].naturalWidth>0)ok++;}"
           "document.getElementById('image-status').textContent='images loaded: '+ok+' of '+im.length;});</script>\n";
  html.insert(html.rfind("</body>"), extra);
  writeFileAtomic(out / "index.html", html);
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
