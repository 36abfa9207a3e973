// writeReport's figure stages across cases: the figure sink, speed against
// error, c_D against Re, and the force histories of unsteady runs.
#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <map>
#include <optional>
#include <sstream>

#include <fmt/format.h>

#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/DetailFields.hpp"
#include "mmval/reports/InputFiles.hpp"
#include "mmval/reports/Site.hpp"
#include "mmval/reports/Summary.hpp"
#include "ReportStages.hpp"

namespace fs = std::filesystem;

namespace mmval::reports::detail {

std::string fileId(const std::string& id) {
  std::string out = id;
  for (char& c : out)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-')) c = '-';
  return out;
}

FigureSink::FigureSink(fs::path out, bool plots) : m_out(std::move(out)), m_plots(plots) { fs::create_directories(m_out / "figures"); }

void FigureSink::addPlot(const std::string& id, const std::string& caption, const Plot& p, const std::string& owner) {
  if (!m_plots) return;
  const std::string file = fileId(id);
  Figure f;
  f.id = id;
  f.caption = caption;
  f.owner = owner;
  f.svg = renderSvg(p);
  f.data = "figures/" + file + ".csv";
  f.data_label = "CSV";
  writeFileAtomic(m_out / "figures" / (file + ".svg"), f.svg);
  writeFileAtomic(m_out / f.data, plotCsv(p));
  m_figures.push_back(std::move(f));
}

void FigureSink::addRendered(Figure f) {
  if (!m_plots) return;
  writeFileAtomic(m_out / "figures" / (fileId(f.id) + ".svg"), f.svg);
  m_figures.push_back(std::move(f));
}

void FigureSink::addImage(const std::string& id, const std::string& caption, const fs::path& png, const std::string& owner, std::string data,
                          std::string data_label, std::string colour_bar) {
  const fs::path canonical = fs::weakly_canonical(png);
  if (std::find(m_images_seen.begin(), m_images_seen.end(), canonical) != m_images_seen.end()) return;
  m_images_seen.push_back(canonical);
  Figure f;
  f.id = id;
  f.caption = caption;
  f.owner = owner;
  f.image = fileId(id) + ".png";
  writeFileAtomic(m_out / "figures" / f.image, readInputFile(png));
  f.data = std::move(data);
  f.data_label = std::move(data_label);
  f.colour_bar = std::move(colour_bar);
  m_figures.push_back(std::move(f));
}

nlohmann::json runOf(const ReportInput& input, const ComparisonInput& c) {
  for (const auto& r : input.summary.results)
    if (r.contains("run_dir") && fs::weakly_canonical(r["run_dir"].get<std::string>()) == fs::weakly_canonical(c.dir)) return r;
  return nullptr;
}

std::string ownerOf(const ReportInput& input, const ComparisonInput& c) {
  const nlohmann::json r = runOf(input, c);
  return r.is_null() ? "compare-" + c.name : pageKey(r);
}

namespace {

/// The family a run's speed-against-error points belong to: its case kind, with the steady and
/// unsteady cylinder apart (their costs differ by orders of magnitude).
std::string speedErrorFamily(const nlohmann::json& r) {
  std::string kind = r["case"].value("kind", std::string("other"));
  if (kind == "cylinder-channel") {
    const nlohmann::json& rc = r.contains("resolved_case") ? r["resolved_case"] : nlohmann::json();
    const bool unsteady = rc.is_object() && rc.contains("numerics") && rc["numerics"].value("mode", std::string()) == "unsteady";
    kind += unsteady ? "-unsteady" : "-steady";
  }
  return kind;
}

/// One run's points of cost against |error|: its CPU seconds when every level with an error
/// recorded them (the machine may be shared: wall time depends on its load), else its wall time.
Series speedErrorSeries(const nlohmann::json& r, bool& cpu) {
  Series s{r["case"]["name"].get<std::string>() + " (" + solverOf(r) + ")", {}, {}, "linespoints"};
  std::vector<double> wall_x, cpu_x;
  for (const DetailRow& level : detailRows(resultDetails(r), DetailField::ladder)) {
    const auto wall = detailNumber(level, DetailField::ladder_wall_seconds), error = detailNumber(level, DetailField::ladder_error);
    if (!wall || !error) continue;
    wall_x.push_back(*wall);
    if (const auto c = detailNumber(level, DetailField::ladder_cpu_seconds)) cpu_x.push_back(*c);
    s.y.push_back(std::abs(*error));
  }
  cpu = !s.y.empty() && cpu_x.size() == s.y.size();
  s.x = cpu ? cpu_x : wall_x;
  if (!cpu) s.name += " (wall time)";
  return s;
}

/// Cost against error over every run that recorded a resolution ladder, one plot per family
/// (arrays, images, steady and unsteady cylinders, ...) with every solver that ran it (mmval and
/// its peers). The cost is CPU seconds where the levels recorded them (series without are marked
/// "wall time"); the error is each level's `error`: the kind's primary metric against the case's
/// reference (the unsteady cylinder: c_D max against the case's first single value for it, e.g.
/// 2D-2's FEATFLOW level 6, else the time-mean c_D).
void speedErrorFigure(const ReportInput& input, FigureSink& sink) {
  struct Family {
    Plot plot;
    int cpu = 0, wall = 0;  // series of each cost
  };
  std::map<std::string, Family> families;
  for (const auto& r : input.summary.results) {
    bool cpu = false;
    Series s = speedErrorSeries(r, cpu);
    if (s.x.empty()) continue;
    const std::string family = speedErrorFamily(r);
    auto [it, added] = families.try_emplace(family, Family{Plot{"Speed against error: " + family, "", "relative error", true, true, {}, 640, 420}});
    ++(cpu ? it->second.cpu : it->second.wall);
    it->second.plot.series.push_back(std::move(s));
  }
  for (auto& [family, f] : families) {
    f.plot.xlabel = f.wall == 0 ? "CPU time (s)" : f.cpu == 0 ? "wall time (s)" : "CPU time (s); wall time for the series marked so";
    const std::string what = family == "cylinder-channel-unsteady"
                                 ? " The error is c_D max's against the case's first single-value reference for it (2D-2: FEATFLOW level 6), or the "
                                   "time-mean c_D's when the case has none."
                                 : "";
    sink.addPlot("speed-vs-error-" + fileId(family),
                 "CPU time (or wall time where a run recorded no CPU time) against relative error over each " + family +
                     " case's resolution ladder, every solver that ran it (log-log)." + what,
                 f.plot);
  }
}

/// Our c_D against Re of the runs set up as the paper's Table 1, by solver, and the
/// Table 1 references their acceptance entries name, by label; `left_out` gets
/// the runs with Re of other set-ups.
std::map<std::string, Series> dragSeries(const ReportInput& input, std::vector<std::string>& left_out) {
  std::map<std::string, Series> by_label;
  for (const auto& r : input.summary.results) {
    const auto re_run = detailNumber(resultDetails(r), DetailField::Re);
    if (!re_run) continue;
    const std::string run_name = r["case"]["name"].get<std::string>();
    if (!paperCylinderSetup(r)) {
      if (std::find(left_out.begin(), left_out.end(), run_name) == left_out.end()) left_out.push_back(run_name);
      continue;
    }
    const double re = *re_run;
    for (const auto& m : r["metrics"]) {
      if (metricOf(m) != "c_D" || !m["value"].is_number()) continue;
      const std::string solver = solverOf(r);
      auto& ours = by_label[solver];
      ours.name = solver;
      ours.style = "points pt 7 ps 1.2";
      if (ours.x.empty() || ours.x.back() != re) {
        ours.x.push_back(re);
        ours.y.push_back(m["value"].get<double>());
      }
      const std::string label = m.value("label", "");
      if (!label.empty() && m["reference"].is_number() && m.value("reference_setup", "") == kTable1Setup) {
        auto& ref = by_label[label];
        ref.name = label;
        ref.style = "points pt 6 ps 1.5";
        ref.x.push_back(re);
        ref.y.push_back(m["reference"].get<double>());
      }
    }
  }
  return by_label;
}

/// c_D against Re: the runs of the paper's Table 1 set-up with those references.
/// Confined benchmarks (Schaefer-Turek, C_d ~5.6 from wall blockage) are a
/// different problem and stay on their own case pages.
void dragFigure(const ReportInput& input, const fs::path& reference_dir, FigureSink& sink) {
  std::vector<std::string> left_out;
  std::map<std::string, Series> by_label = dragSeries(input, left_out);
  // The paper's Table 1 columns at every Re it lists (reference-data/); they replace
  // the same references taken from the runs' acceptance entries.
  if (!by_label.empty())
    if (const auto t1 = cylinderDragTable(input, reference_dir)) {
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
  for (auto& entry : by_label) p.series.push_back(entry.second);
  if (p.series.empty() || by_label.begin()->second.x.size() + by_label.rbegin()->second.x.size() < 2) return;
  sink.addPlot("cd-vs-re",
               "Drag coefficient against Re of the paper's Table 1 set-up (one cylinder in unbounded flow): our runs (filled) and the references (open): "
               "the columns of the paper's Table 1 ([66]-[69]: the models of the references the paper quotes, as Table 1's note says) and those the runs' "
               "acceptance entries name." +
                   (left_out.empty() ? std::string()
                                     : " Not on these axes (other set-ups, e.g. confined channels whose walls raise C_d): " +
                                           fmt::format("{}", fmt::join(left_out, ", ")) + "; see their case pages."),
               p);
}

}  // namespace

void crossCaseFigures(const ReportInput& input, const fs::path& reference_dir, FigureSink& sink) {
  speedErrorFigure(input, sink);
  dragFigure(input, reference_dir, sink);
}

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

namespace {

/// c_D and c_L against time of one run's forces.csv, the part in the statistics
/// window [w0, w1] in its own colour; empty series are left out.
std::array<Series, 4> forceSeries(const std::vector<std::vector<double>>& cols, double w0, double w1) {
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
  return s;
}

}  // namespace

void forceHistoryFigures(const ReportInput& input, FigureSink& sink) {
  for (const auto& r : input.summary.results) {
    const auto window = detailNumbers(resultDetails(r), DetailField::statistics_window_s);  // [begin, end], declared with two entries
    if (!window || !std::isfinite((*window)[0]) || !std::isfinite((*window)[1]) || !r.contains("run_dir")) continue;
    const fs::path file = fs::path(r["run_dir"].get<std::string>()) / "forces.csv";
    if (!fs::exists(file)) continue;
    const auto cols = readColumns(file);
    if (cols.size() < 3 || cols[0].empty()) continue;
    const double w0 = (*window)[0], w1 = (*window)[1];
    std::array<Series, 4> s = forceSeries(cols, w0, w1);
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
    sink.addPlot(name + "-forces",
                 fmt::format("Drag and lift coefficients against time ({}; y range of the statistics window); statistics window {:.4g} - {:.4g} s ({} shedding "
                             "periods): c_D max {}, c_L max {}, St {}.",
                             name, w0, w1, detailInteger(resultDetails(r), DetailField::shedding_periods).value_or(0), metric("c_D_max"),
                             metric("c_L_max"), metric("St")),
                 p, pageKey(r));
  }
}

}  // namespace mmval::reports::detail
