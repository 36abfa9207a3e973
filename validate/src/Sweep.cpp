#include "mmval/validate/Sweep.hpp"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>

#include <sys/wait.h>
#include <thread>

#include <fmt/format.h>

#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/JsonNumbers.hpp"
#include "mmval/core/Resources.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/reports/Plot.hpp"
#include "mmval/validate/RunFolders.hpp"

#include "ChildProcesses.hpp"

namespace fs = std::filesystem;

namespace mmval::validate {

namespace {

constexpr int kMaxRuns = 1000;  ///< a guard against a mistyped product of axes

/// What sweep.json's uncertainty is, in its own words (metricUncertainty, discretisationPart).
constexpr const char* kUncertaintyRule =
    "per metric and per setting of the axes that are neither grid nor step, at the finest grid and finest step: value = mean over the seeds, "
    "seed_se = its standard error; grid and step parts = |mean(finest) - mean(next)| of that axis (the other one at its finest), its standard error from the per-seed "
    "differences when both levels ran the same seeds (difference_se_rule paired), else sqrt(se1^2 + se2^2) (independent), or with three "
    "levels whose differences have one sign, shrink towards the finest and are both beyond 2 standard errors the Richardson estimate "
    "|difference| / (r^p - 1) with the observed order p (Celik et al. 2008); combined = sqrt(seed_se^2 + grid^2 + step^2) over the parts "
    "estimated; converged = on every discretisation axis both |difference| and the part within converged_within, converged_2se = also part + 2 part_se";

InputLocation option(const std::string& name) { return {"(command line)", 0, 0, name}; }

/// One run of the sweep: its setting (one value per axis), its seed and its result.
struct SweepRun {
  std::vector<std::string> values;
  std::optional<std::int64_t> seed;
  std::string folder;
  std::string status = "ok";   ///< ok, metrics failed, numerical failure: ...
  std::map<std::string, double> metrics;
  double wall_seconds = 0;
};

std::string seedKeyOf(const Schema& schema, const std::string& given) {
  if (!given.empty()) {
    if (schema.find(given) == nullptr) throw InputError(option("--seed-key"), "the case kind '" + schema.kind() + "' has no such key", given, "a key of the kind (mmval case-doc " + schema.kind() + ")");
    return given;
  }
  std::vector<std::string> found;
  for (const auto& k : schema.keys())
    if (k.key == "seed" || (k.key.size() > 5 && k.key.compare(k.key.size() - 5, 5, ".seed") == 0)) found.push_back(k.key);
  if (found.size() != 1)
    throw InputError(option("--seeds"), found.empty() ? "the case kind '" + schema.kind() + "' has no seed key (its runs are deterministic)"
                                                      : "the case kind '" + schema.kind() + "' has several seed keys",
                     {}, found.empty() ? "no --seeds for this kind" : "--seed-key naming one of them");
  return found.front();
}

/// Every combination of the axes' values, the first axis varying slowest.
std::vector<std::vector<std::string>> settings(const std::vector<SweepAxis>& axes) {
  std::vector<std::vector<std::string>> out = {{}};
  for (const auto& a : axes) {
    std::vector<std::vector<std::string>> next;
    for (const auto& prefix : out)
      for (const auto& v : a.values) {
        next.push_back(prefix);
        next.back().push_back(v);
      }
    out = std::move(next);
  }
  return out;
}

/// The grid and step axes of a sweep (indices into its axes; -1: none), their values as numbers.
struct Discretisation {
  int grid = -1, step = -1;
  Finer grid_finer = Finer::larger, step_finer = Finer::smaller;
  std::vector<double> grid_values, step_values;
  double tolerance = std::numeric_limits<double>::quiet_NaN();  ///< every metric without its own; NaN: no verdict
  std::map<std::string, double> tolerances;                      ///< per metric
  std::vector<std::string> shown;                                ///< --metric: the metrics `tolerance` is for (empty: all)
  double toleranceOf(const std::string& metric) const {
    const auto it = tolerances.find(metric);
    if (it != tolerances.end()) return it->second;
    return shown.empty() || std::find(shown.begin(), shown.end(), metric) != shown.end() ? tolerance : std::numeric_limits<double>::quiet_NaN();
  }
};

/// A value as people read it: a TOML string's text without its quotes.
std::string shown(const std::string& v) {
  return v.size() >= 2 && v.front() == '"' && v.back() == '"' ? v.substr(1, v.size() - 2) : v;
}

/// A value of a discretisation axis as a number: a TOML number, or a quoted
/// quantity ("0.01 s") whose unit text every value of the axis shares.
/// `unit`: kUnsetUnit before the axis's first value, then that value's unit text.
constexpr const char* kUnsetUnit = "\x01";
double axisNumber(const std::string& option_name, const SweepAxis& axis, const std::string& value, std::string& unit) {
  const std::string text = shown(value);
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  std::string rest = end == text.c_str() ? text : std::string(end);
  rest.erase(0, rest.find_first_not_of(' '));
  if (end == text.c_str() || !std::isfinite(v) || v <= 0 || (value.front() != '"' && !rest.empty()))
    throw InputError(option(option_name), "a discretisation axis needs positive numbers", axis.key + "=" + value, "numbers such as 0.5,1,2");
  if (unit == kUnsetUnit) unit = rest;
  if (rest != unit)
    throw InputError(option(option_name), "the values of a discretisation axis have different units", axis.key + "=" + value, "one unit for every value");
  return v;
}

Discretisation discretisationOf(const SweepOptions& o, const std::vector<SweepAxis>& axes) {
  Discretisation d;
  d.shown = o.metrics;
  d.grid_finer = o.grid_finer;
  d.step_finer = o.step_finer;
  const auto axisIndex = [&](const std::string& name, const std::string& key, std::vector<double>& values) {
    if (key.empty()) return -1;
    std::string keys;
    for (std::size_t i = 0; i < axes.size(); ++i) {
      keys += (i ? ", " : "") + axes[i].key;
      if (axes[i].key != key) continue;
      if (axes[i].values.size() < 2) throw InputError(option(name), "a discretisation axis needs at least two values", key, "--vary " + key + "=V1,V2[,V3]");
      std::string unit = kUnsetUnit;
      for (const auto& v : axes[i].values) values.push_back(axisNumber(name, axes[i], v, unit));
      return static_cast<int>(i);
    }
    throw InputError(option(name), "the key is not one of the --vary keys", key, keys.empty() ? "--vary " + key + "=V1,V2,V3" : "one of: " + keys);
  };
  d.grid = axisIndex("--grid", o.grid_key, d.grid_values);
  d.step = axisIndex("--step", o.step_key, d.step_values);
  if (d.grid >= 0 && d.grid == d.step) throw InputError(option("--step"), "the grid axis is also the step axis", o.step_key, "two different --vary keys");
  for (const auto& text : o.converged_within) {
    const std::size_t eq = text.find('=');
    const std::string value = eq == std::string::npos ? text : text.substr(eq + 1);
    char* end = nullptr;
    const double v = std::strtod(value.c_str(), &end);
    if (end == value.c_str() || *end != '\0' || !(v > 0) || !std::isfinite(v) || eq == 0)
      throw InputError(option("--converged-within"), "not a positive number or METRIC=number", text, "an absolute tolerance in the metric's unit, e.g. 0.02 or retained_fraction=0.02");
    (eq == std::string::npos ? d.tolerance : d.tolerances[text.substr(0, eq)]) = v;
  }
  return d;
}

void readMetrics(const nlohmann::json& result, SweepRun& run, std::map<std::string, std::string>& units) {
  run.wall_seconds = result.at("cost").at("wall_seconds").get<double>();
  for (const auto& m : result.at("metrics")) {
    // By the metric's own name: a metric checked against several references has one row per
    // reference, named "metric (label)", and the same value in each.
    const std::string name = m.contains("metric") ? m.at("metric").get<std::string>() : m.at("name").get<std::string>();
    if (run.metrics.count(name) != 0) continue;
    run.metrics[name] = m.at("value").is_number() ? m.at("value").get<double>() : std::numeric_limits<double>::quiet_NaN();
    units.emplace(name, m.value("unit", ""));
  }
  if (!result.value("all_pass", true)) run.status = "metrics failed";
}

std::string csvCell(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char ch : s) q += ch == '"' ? std::string("\"\"") : std::string(1, ch);
  return q + "\"";
}

std::string number(double v) { return std::isfinite(v) ? fmt::format("{:.9g}", v) : std::string(); }

nlohmann::json partJson(const DiscretisationPart& p, const std::string& key) {
  nlohmann::json levels = nlohmann::json::array();
  for (const auto& l : p.levels)
    levels.push_back({{"level", l.value}, {"n", l.stats.n}, {"mean", finiteOrNull(l.stats.mean)}, {"se", l.stats.n > 1 ? finiteOrNull(l.stats.se) : nlohmann::json(nullptr)}});
  return {{"key", key}, {"method", p.method}, {"note", p.note}, {"levels", levels}, {"difference", finiteOrNull(p.difference)},
          {"difference_se", finiteOrNull(p.difference_se)},
          {"difference_se_rule", p.difference_se_rule.empty() ? nlohmann::json(nullptr) : nlohmann::json(p.difference_se_rule)},
          {"paired_seeds", p.paired_seeds}, {"resolved", p.resolved}, {"observed_order", finiteOrNull(p.observed_order)},
          {"extrapolated", finiteOrNull(p.extrapolated)}, {"part", finiteOrNull(p.part)}, {"part_se", finiteOrNull(p.part_se)}};
}

/// Index of the finest value of an axis.
std::size_t finestIndex(const std::vector<double>& values, Finer finer) {
  const auto it = finer == Finer::larger ? std::max_element(values.begin(), values.end()) : std::min_element(values.begin(), values.end());
  return static_cast<std::size_t>(it - values.begin());
}

/// Per setting (one value per axis, in the order of the groups): the statistics of every metric.
struct GroupStats {
  std::vector<std::vector<std::string>> values;
  std::vector<std::map<std::string, SampleStats>> stats;
  std::vector<std::map<std::string, std::vector<double>>> by_seed;  ///< the values in seed order (NaN: none), for pairing
};

/// sweep.json's "uncertainty": per metric, per setting of the axes that are neither grid nor step.
nlohmann::json uncertaintyJson(const std::vector<SweepAxis>& axes, const Discretisation& d, const GroupStats& g, const std::map<std::string, std::string>& units) {
  const auto other = [&](const std::vector<std::string>& v) {
    std::vector<std::string> o;
    for (std::size_t a = 0; a < v.size(); ++a)
      if (static_cast<int>(a) != d.grid && static_cast<int>(a) != d.step) o.push_back(v[a]);
    return o;
  };
  std::vector<std::vector<std::string>> others;
  for (const auto& v : g.values)
    if (std::find(others.begin(), others.end(), other(v)) == others.end()) others.push_back(other(v));
  const std::string fine_grid = d.grid >= 0 ? axes[d.grid].values[finestIndex(d.grid_values, d.grid_finer)] : std::string();
  const std::string fine_step = d.step >= 0 ? axes[d.step].values[finestIndex(d.step_values, d.step_finer)] : std::string();
  nlohmann::json out = nlohmann::json::object();
  for (const auto& [name, unit] : units) {
    nlohmann::json list = nlohmann::json::array();
    for (const auto& o : others) {
      SampleStats finest;
      std::vector<LadderLevel> grid_levels, step_levels;
      nlohmann::json setting = nlohmann::json::object(), at = nlohmann::json::object();
      for (std::size_t i = 0; i < g.values.size(); ++i) {
        const auto& v = g.values[i];
        if (other(v) != o) continue;
        const bool grid_fine = d.grid < 0 || v[d.grid] == fine_grid, step_fine = d.step < 0 || v[d.step] == fine_step;
        const auto it = g.stats[i].find(name);
        const SampleStats s = it == g.stats[i].end() ? SampleStats{} : it->second;
        const auto seeds = g.by_seed[i].find(name);
        const std::vector<double> by_seed = seeds == g.by_seed[i].end() ? std::vector<double>{} : seeds->second;
        if (grid_fine && step_fine) {
          finest = s;
          for (std::size_t a = 0; a < axes.size(); ++a)
            (static_cast<int>(a) == d.grid || static_cast<int>(a) == d.step ? at : setting)[axes[a].key] = shown(v[a]);
        }
        const auto index = [&](int axis) { return static_cast<std::size_t>(std::find(axes[axis].values.begin(), axes[axis].values.end(), v[axis]) - axes[axis].values.begin()); };
        if (d.grid >= 0 && step_fine) grid_levels.push_back({d.grid_values[index(d.grid)], s, by_seed});
        if (d.step >= 0 && grid_fine) step_levels.push_back({d.step_values[index(d.step)], s, by_seed});
      }
      std::optional<DiscretisationPart> grid, step;
      if (d.grid >= 0) grid = discretisationPart(grid_levels, d.grid_finer);
      if (d.step >= 0) step = discretisationPart(step_levels, d.step_finer);
      const MetricUncertainty u = metricUncertainty(finest, grid, step, d.toleranceOf(name));
      list.push_back({{"setting", setting}, {"at", at}, {"value", finest.n ? finiteOrNull(finest.mean) : nlohmann::json(nullptr)}, {"n", finest.n},
                      {"seed_se", finiteOrNull(u.seed_se)}, {"grid", grid ? partJson(*grid, axes[d.grid].key) : nlohmann::json(nullptr)},
                      {"step", step ? partJson(*step, axes[d.step].key) : nlohmann::json(nullptr)}, {"combined", finiteOrNull(u.combined)},
                      {"converged", u.converged ? nlohmann::json(*u.converged) : nlohmann::json(nullptr)},
                      {"converged_2se", u.converged_2se ? nlohmann::json(*u.converged_2se) : nlohmann::json(nullptr)}, {"verdict", u.verdict}});
    }
    out[name] = {{"unit", unit}, {"tolerance", finiteOrNull(d.toleranceOf(name))}, {"settings", list}};
  }
  return out;
}

std::string numberOrDash(const nlohmann::json& v, int digits, bool sign = false) {
  if (!v.is_number()) return "-";
  return sign ? fmt::format("{:+.{}g}", v.get<double>(), digits) : fmt::format("{:.{}g}", v.get<double>(), digits);
}

/// One discretisation part in a line: "grid 0.004 (richardson, order 2.1; 2 vs 1: -0.004 +- 0.01, within seed noise)".
std::string partText(const char* what, const nlohmann::json& p) {
  if (p.is_null()) return {};
  std::string t = fmt::format("; {} {}", what, numberOrDash(p["part"], 3));
  if (p["method"] == "none") return t + " (" + p["note"].get<std::string>() + ")";
  const auto& l = p["levels"];
  t += fmt::format(" ({}{}; {:g} vs {:g}: {} +- {}{}{})", p["method"].get<std::string>(),
                   p["observed_order"].is_number() ? fmt::format(", order {:.2g}", p["observed_order"].get<double>()) : std::string(), l[0]["level"].get<double>(),
                   l[1]["level"].get<double>(), numberOrDash(p["difference"], 3, true), numberOrDash(p["difference_se"], 2),
                   p["difference_se_rule"] == "paired" ? fmt::format(" paired over {} seeds", p["paired_seeds"].get<int>()) : std::string(),
                   p["resolved"].get<bool>() ? "" : ", within seed noise");
  return t;
}

/// The terminal lines of one metric's uncertainty.
std::string uncertaintyText(const nlohmann::json& u) {
  std::string t;
  for (const auto& s : u["settings"]) {
    std::string label;
    for (const auto& [k, v] : s["at"].items()) label += (label.empty() ? "" : ", ") + k + "=" + v.get<std::string>();
    for (const auto& [k, v] : s["setting"].items()) label += (label.empty() ? "" : ", ") + k + "=" + v.get<std::string>();
    t += fmt::format("  uncertainty at {}: {} (n {}); seed SE {}{}{}; combined {}{}\n", label.empty() ? "(case as written)" : label,
                     numberOrDash(s["value"], 5), s["n"].get<int>(), numberOrDash(s["seed_se"], 2), partText("grid", s["grid"]),
                     partText("step", s["step"]), numberOrDash(s["combined"], 2), s["verdict"].get<std::string>().empty() ? "" : "; " + s["verdict"].get<std::string>());
  }
  return t;
}

struct Tables {
  std::string csv, text;
  nlohmann::json json;
};

/// sweep.csv (one row per run), sweep.json (per setting over seeds, the band
/// over settings and each key's effect) and the terminal table.
Tables tabulate(const std::vector<SweepAxis>& axes, const std::vector<SweepRun>& runs, const std::map<std::string, std::string>& units,
                const std::vector<std::string>& chosen, int per_setting, const Discretisation& d) {
  std::vector<std::string> names;
  for (const auto& [name, unit] : units) names.push_back(name);
  Tables t;
  t.csv = "run,status,seed";
  for (const auto& a : axes) t.csv += "," + csvCell(a.key);
  t.csv += ",wall_s";
  for (const auto& n : names) t.csv += "," + csvCell(n);
  t.csv += "\n";
  for (const auto& r : runs) {
    t.csv += r.folder + "," + csvCell(r.status) + "," + (r.seed ? std::to_string(*r.seed) : std::string());
    for (const auto& v : r.values) t.csv += "," + csvCell(shown(v));
    t.csv += "," + number(r.wall_seconds);
    for (const auto& n : names) t.csv += "," + number(r.metrics.count(n) ? r.metrics.at(n) : std::nan(""));
    t.csv += "\n";
  }
  const auto column = [&](const std::string& name, std::size_t first, std::size_t count) {
    std::vector<double> v;
    for (std::size_t i = first; i < first + count; ++i) v.push_back(runs[i].metrics.count(name) ? runs[i].metrics.at(name) : std::nan(""));
    return v;
  };
  nlohmann::json groups = nlohmann::json::array();
  std::map<std::string, std::vector<double>> means;
  GroupStats group_stats;
  for (std::size_t g = 0; g * per_setting < runs.size(); ++g) {
    nlohmann::json setting = nlohmann::json::object(), stats = nlohmann::json::object();
    for (std::size_t a = 0; a < axes.size(); ++a) setting[axes[a].key] = shown(runs[g * per_setting].values[a]);
    group_stats.values.push_back(runs[g * per_setting].values);
    group_stats.stats.emplace_back();
    group_stats.by_seed.emplace_back();
    for (const auto& n : names) {
      const std::vector<double> values = column(n, g * per_setting, per_setting);
      const SampleStats s = sampleStats(values);
      group_stats.by_seed.back()[n] = values;
      stats[n] = s.toJson();
      group_stats.stats.back()[n] = s;
      means[n].push_back(s.n > 0 ? s.mean : std::nan(""));
    }
    groups.push_back({{"setting", setting}, {"runs", per_setting}, {"metrics", stats}});
  }
  nlohmann::json band = nlohmann::json::object(), effects = nlohmann::json::object();
  for (const auto& n : names) {
    const SampleStats over = sampleStats(means[n]);
    band[n] = {{"unit", units.at(n)}, {"min_of_means", over.n ? nlohmann::json(over.min) : nlohmann::json(nullptr)},
               {"max_of_means", over.n ? nlohmann::json(over.max) : nlohmann::json(nullptr)}};
    for (std::size_t a = 0; a < axes.size(); ++a) {
      // Each key's main effect: the spread of the means over its values, every other key pooled.
      std::vector<double> marginal;
      for (const auto& v : axes[a].values) {
        std::vector<double> pool;
        for (const auto& r : runs)
          if (r.values[a] == v && r.metrics.count(n)) pool.push_back(r.metrics.at(n));
        const SampleStats s = sampleStats(pool);
        if (s.n > 0) marginal.push_back(s.mean);
      }
      const SampleStats m = sampleStats(marginal);
      effects[axes[a].key][n] = m.n ? nlohmann::json(m.max - m.min) : nlohmann::json(nullptr);
    }
  }
  const nlohmann::json uncertainty = uncertaintyJson(axes, d, group_stats, units);
  t.json = {{"groups", groups}, {"band", band}, {"effects", effects}, {"uncertainty", uncertainty}};
  // The terminal: the chosen metrics (all when none chosen) per setting, mean +- standard error.
  for (const auto& n : names) {
    if (!chosen.empty() && std::find(chosen.begin(), chosen.end(), n) == chosen.end()) continue;
    t.text += fmt::format("{} [{}]\n", n, units.at(n));
    for (const auto& g : groups) {
      const auto& s = g["metrics"][n];
      std::string label;
      for (const auto& [k, v] : g["setting"].items()) label += (label.empty() ? "" : ", ") + k + "=" + v.get<std::string>();
      t.text += fmt::format("  {:<50} {} (n {})\n", label.empty() ? "(case as written)" : label,
                            s["n"].get<int>() == 0 ? std::string("-")
                                                   : fmt::format("{:.5g} +- {:.2g}", s["mean"].get<double>(), s["se"].get<double>()),
                            s["n"].get<int>());
    }
    t.text += uncertaintyText(uncertainty[n]);
  }
  return t;
}

/// The first chosen metric against axis `x` (the grid axis, else the first), one line per other setting, error bars = standard error over seeds.
std::optional<std::string> plotSvg(const std::vector<SweepAxis>& axes, const nlohmann::json& groups, const std::string& metric,
                                   const std::string& unit, std::size_t x) {
  if (axes.empty() || !reports::gnuplotAvailable()) return std::nullopt;
  reports::Plot p;
  p.title = "mmval sweep: " + metric + " (mean +- standard error over seeds)";
  p.xlabel = axes[x].key + " (";
  for (std::size_t i = 0; i < axes[x].values.size(); ++i) p.xlabel += (i ? ", " : "") + std::to_string(i) + ": " + shown(axes[x].values[i]);
  p.xlabel += ")";
  p.ylabel = metric + (unit.empty() || unit == "1" ? "" : " [" + unit + "]");
  // gnuplot's axis labels are enhanced text: "_" would start a subscript.
  for (std::string* label : {&p.xlabel, &p.ylabel})
    for (std::size_t at = 0; (at = label->find('_', at)) != std::string::npos; at += 2) label->insert(at, "\\");
  std::map<std::string, reports::Series> lines;
  for (const auto& g : groups) {
    std::string rest;
    int index = 0;
    for (const auto& [k, v] : g["setting"].items()) {
      if (k == axes[x].key) {
        const auto& vals = axes[x].values;
        const std::string value = v.get<std::string>();  // a named copy: clang 14 cannot capture a structured binding
        index = static_cast<int>(std::find_if(vals.begin(), vals.end(), [&](const std::string& x) { return shown(x) == value; }) - vals.begin());
      } else {
        rest += (rest.empty() ? "" : ", ") + k + "=" + v.get<std::string>();
      }
    }
    const auto& s = g["metrics"][metric];
    if (s["n"].get<int>() == 0) continue;
    auto& line = lines[rest];
    line.name = rest.empty() ? metric : rest;
    line.style = "yerrorlines";
    line.x.push_back(index);
    line.y.push_back(s["mean"].get<double>());
    line.yerr.push_back(s["se"].get<double>());
  }
  for (auto& [k, line] : lines) p.series.push_back(line);
  if (p.series.empty()) return std::nullopt;
  return reports::renderSvg(p);
}

/// Says which run starts ("sweep [i/n] run-NNN: KEY=VALUE ...") and, under --resume, returns its
/// complete earlier run (said on the terminal), which is then kept, not run again. Both ways of
/// running a sweep (one process, child processes) start their runs here.
std::optional<nlohmann::json> startRun(const SweepOptions& o, const Case& c, std::size_t i, std::size_t n, const SweepRun& r, const fs::path& dir) {
  std::string label;
  for (const auto& ov : c.overrides()) label += " " + ov.text();
  std::fprintf(stderr, "sweep [%zu/%zu] %s:%s\n", i + 1, n, r.folder.c_str(), label.c_str());
  std::optional<nlohmann::json> earlier = o.resume ? earlierRun(c, dir) : std::nullopt;
  if (earlier) std::fprintf(stderr, "      kept the complete earlier run (same case and settings)\n");
  return earlier;
}

// ---- --jobs N: the runs as child processes ---------------------------------

using detail::fileText;
using detail::messageAfter;
using detail::statusText;

/// While it lives, the runs started as children get their share of the cores for a thread count of
/// "auto" (numerics.threads = 0): the hardware's cores / jobs, at least 1, in kAutoThreadsVariable,
/// unless that is set already (the user's own share is kept). Without it N runs at once would each
/// take every core.
class CoreShare {
 public:
  explicit CoreShare(int jobs) {
    if (std::getenv(kAutoThreadsVariable) != nullptr) return;
    const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
    ::setenv(kAutoThreadsVariable, std::to_string(std::max(1u, cores / static_cast<unsigned>(jobs))).c_str(), 1);
    m_set = true;
  }
  ~CoreShare() {
    if (m_set) ::unsetenv(kAutoThreadsVariable);
  }
  CoreShare(const CoreShare&) = delete;
  CoreShare& operator=(const CoreShare&) = delete;

 private:
  bool m_set = false;
};

/// The runs of a sweep `jobs` at a time, each in a child process running `mmval run` with the
/// run's overrides as --set (their text form is what --set parses, so each reads back as given;
/// the case hash in the child's result.json checks it). Fills results[i] (none: a numerical
/// failure, recorded in runs[i].status). A child that fails otherwise ends the sweep once the
/// others have finished.
void runChildren(const SweepOptions& o, const std::vector<Case>& cases, std::vector<SweepRun>& runs, const fs::path& out,
                 std::vector<std::optional<nlohmann::json>>& results) {
  const std::string executable = o.executable.empty() ? std::string("/proc/self/exe") : o.executable;
  const CoreShare share(o.jobs);
  detail::Children children;
  std::size_t next = 0, finished = 0;
  std::string fatal;
  int fatal_status = -1;
  const auto finishedLine = [&](const SweepRun& r, const std::string& what) {
    ++finished;
    std::fprintf(stderr, "sweep [%zu/%zu done] %s: %s\n", finished, runs.size(), r.folder.c_str(), what.c_str());
  };
  while ((next < runs.size() && fatal.empty()) || children.size() > 0) {
    while (next < runs.size() && fatal.empty() && children.size() < static_cast<std::size_t>(o.jobs)) {
      const std::size_t i = next++;
      SweepRun& r = runs[i];
      if ((results[i] = startRun(o, cases[i], i, runs.size(), r, out / "runs" / r.folder))) {
        ++finished;
        continue;
      }
      std::vector<std::string> args = {"mmval", "run", o.file, "--out", (out / "runs" / r.folder).string(), "--quiet"};
      for (const auto& ov : cases[i].overrides()) {
        args.push_back("--set");
        args.push_back(ov.text());
      }
      if (o.resume) args.push_back("--resume");
      children.start(executable, args, {-1, i, out / "runs" / (r.folder + ".log"), std::chrono::steady_clock::now()});
    }
    if (children.size() == 0) continue;
    auto [c, status] = children.wait();
    SweepRun& r = runs[c.index];
    const fs::path dir = out / "runs" / r.folder;
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - c.start).count();
    const int code = status >= 0 && WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    const std::string log = fileText(c.log);
    std::error_code ec;
    if (code == static_cast<int>(ExitCode::ok) || code == static_cast<int>(ExitCode::metric_failed)) {
      results[c.index] = earlierRun(cases[c.index], dir);
      if (results[c.index]) {
        fs::remove(c.log, ec);
        finishedLine(r, fmt::format("{} ({:.1f} s)", code == 0 ? "ok" : "metrics failed", seconds));
        continue;
      }
      if (fatal.empty()) {
        fatal = fmt::format("{} ended with {} but {} is missing or is the result of another case (its case hash differs); its output is in {}",
                            r.folder, statusText(status), (dir / "result.json").string(), c.log.string());
        fatal_status = static_cast<int>(ExitCode::internal);
      }
    } else if (code == static_cast<int>(ExitCode::numerical)) {
      // One setting the numerics cannot do does not end the sweep; it is listed as such (as in one process).
      const std::string cause = messageAfter(log, "mmval: numerical failure: ");
      r.status = "numerical failure: " + (cause.empty() ? "exit status 5; its output was in " + c.log.string() : cause);
      fs::remove(c.log, ec);
      finishedLine(r, r.status);
    } else if (fatal.empty()) {
      const std::string said = messageAfter(log, "mmval: ");
      fatal = fmt::format("{} ({}) failed: `mmval run` ended with {}{}; its output is in {}", r.folder, dir.string(), statusText(status),
                          said.empty() ? std::string() : ": " + said, c.log.string());
      fatal_status = code;
      std::fprintf(stderr, "sweep: %s; waiting for the %zu run(s) still going\n", fatal.c_str(), children.size());
    }
  }
  if (fatal.empty()) return;
  const std::string message = "the sweep stopped: " + fatal;
  if (fatal_status == static_cast<int>(ExitCode::usage) || fatal_status == static_cast<int>(ExitCode::bad_input))
    throw InputError(option("--jobs"), message, {}, "the run's own error in its log; mmval run with the same --set reproduces it");
  throw std::runtime_error(message);
}

}  // namespace

void runSweep(const SweepOptions& o, const CaseKindRegistry& registry) {
  std::vector<CaseOverride> base;
  for (const auto& s : o.set) base.push_back(CaseOverride::parse(s));
  const Case first = Case::load(o.file, registry, base);
  std::vector<SweepAxis> axes;
  for (const auto& v : o.vary) axes.push_back(parseSweepAxis(v));
  for (std::size_t i = 0; i < axes.size(); ++i)
    for (std::size_t j = 0; j < i; ++j)
      if (axes[i].key == axes[j].key) throw InputError(option("--vary"), "the key is varied twice", axes[i].key, "each key in one --vary");
  const Discretisation disc = discretisationOf(o, axes);
  if (o.jobs < 1) throw InputError(option("--jobs"), "not a positive number of runs at once", std::to_string(o.jobs), "1 (one after another) or more");
  for (const char* rank_variable : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE"})
    if (o.jobs > 1 && std::getenv(rank_variable) != nullptr)
      throw InputError(option("--jobs"), "the sweep runs under mpirun, and its children would take its MPI ranks' places", std::to_string(o.jobs),
                       "--jobs 1 under mpirun (each run on the ranks), or --jobs N without mpirun (each run on one rank)");
  const std::string seed_key = o.seeds > 0 || !o.seed_key.empty() ? seedKeyOf(registry.schema(first.kind()), o.seed_key) : std::string();
  const int seeds = std::max(o.seeds, seed_key.empty() ? 0 : 1);
  const auto combos = settings(axes);
  const std::size_t total = combos.size() * static_cast<std::size_t>(std::max(seeds, 1));
  if (total > static_cast<std::size_t>(kMaxRuns))
    throw InputError(option("--vary"), fmt::format("the sweep has {} runs", total), {}, fmt::format("at most {} runs", kMaxRuns));

  // Every run's case is loaded (and so checked) before the first one runs.
  std::vector<SweepRun> runs;
  std::vector<Case> cases;
  for (const auto& combo : combos)
    for (int s = 1; s <= std::max(seeds, 1); ++s) {
      std::vector<CaseOverride> ov = base;
      for (std::size_t a = 0; a < axes.size(); ++a) ov.push_back({axes[a].key, combo[a]});
      SweepRun r;
      r.values = combo;
      if (seeds > 0) {
        ov.push_back({seed_key, std::to_string(s)});
        r.seed = s;
      }
      r.folder = fmt::format("run-{:03}", runs.size() + 1);
      cases.push_back(Case::load(o.file, registry, ov));
      runs.push_back(std::move(r));
    }

  const fs::path out = normaliseOutputPath(o.out);
  requireOwnedFolder(out);
  fs::create_directories(out / "runs");
  const FolderLock lock(out, out.string());
  writeOutputMarker(out);
  std::map<std::string, std::string> units;
  if (o.jobs > 1) {
    std::vector<std::optional<nlohmann::json>> results(runs.size());
    runChildren(o, cases, runs, out, results);
    for (std::size_t i = 0; i < runs.size(); ++i)  // in run order, as one process reads them
      if (results[i]) readMetrics(*results[i], runs[i], units);
  } else {
    for (std::size_t i = 0; i < runs.size(); ++i) {
      SweepRun& r = runs[i];
      const fs::path dir = out / "runs" / r.folder;
      std::optional<nlohmann::json> result = startRun(o, cases[i], i, runs.size(), r, dir);
      if (!result) {
        try {
          result = runCase(cases[i], registry, dir, {o.quiet, o.resume}).result;
        } catch (const NumericalFailure& e) {
          // One setting the numerics cannot do does not end the sweep; it is listed as such.
          r.status = std::string("numerical failure: ") + e.what();
          std::fprintf(stderr, "      %s\n", r.status.c_str());
        }
      }
      if (result) readMetrics(*result, r, units);
    }
  }

  for (const auto& metric : o.metrics)
    if (units.count(metric) == 0) std::fprintf(stderr, "sweep: no run reported %s (a metric some runs leave out when it did not happen)\n", metric.c_str());
  for (const auto& [metric, tolerance] : disc.tolerances)
    if (units.count(metric) == 0) std::fprintf(stderr, "sweep: --converged-within names %s, which no run reported (no verdict for it)\n", metric.c_str());
  const int per_setting = std::max(seeds, 1);
  const Tables t = tabulate(axes, runs, units, o.metrics, per_setting, disc);
  nlohmann::json doc = {{"schema", "mmval-sweep/1"}, {"case", {{"name", first.name()}, {"kind", first.kind()}, {"file", first.file().string()}}}};
  nlohmann::json ax = nlohmann::json::array();
  for (const auto& a : axes) ax.push_back({{"key", a.key}, {"values", a.values}});
  doc["axes"] = ax;
  doc["seed_key"] = seed_key.empty() ? nlohmann::json(nullptr) : nlohmann::json(seed_key);
  doc["seeds_per_setting"] = seeds;
  doc["set"] = o.set;
  doc["metrics_shown"] = o.metrics;
  const auto axisJson = [&](int axis, Finer finer) {
    return axis < 0 ? nlohmann::json(nullptr) : nlohmann::json{{"key", axes[axis].key}, {"finer", finer == Finer::larger ? "larger" : "smaller"}};
  };
  doc["discretisation"] = {{"grid", axisJson(disc.grid, disc.grid_finer)},
                           {"step", axisJson(disc.step, disc.step_finer)},
                           {"converged_within", finiteOrNull(disc.tolerance)},
                           {"converged_within_metric", disc.tolerances},
                           {"rule", kUncertaintyRule}};
  doc["runs"] = runs.size();
  doc["failed_runs"] = std::count_if(runs.begin(), runs.end(), [](const SweepRun& r) { return r.status.rfind("numerical", 0) == 0; });
  doc.update(t.json);
  doc["note"] = "se is the standard error of the mean over the seeds of a setting (sd / sqrt(n)); band is the range of the setting means; "
                "effects[key][metric] is the range of the means over that key's values with every other key pooled";
  std::vector<std::string> files = {"sweep.csv", "sweep.json"};
  writeFileAtomic(out / "sweep.csv", t.csv);
  writeFileAtomic(out / "sweep.json", doc.dump(2) + "\n");
  const std::string plotted = !o.metrics.empty() ? o.metrics.front() : std::string();
  if (!plotted.empty() && units.count(plotted) != 0) {
    if (auto svg = plotSvg(axes, doc["groups"], plotted, units.at(plotted), disc.grid >= 0 ? static_cast<std::size_t>(disc.grid) : 0)) {
      writeFileAtomic(out / "sweep.svg", *svg);
      files.push_back("sweep.svg");
    }
  }
  writeOutputMarker(out);
  std::fputs(t.text.c_str(), stdout);
  std::printf("sweep: %zu run(s) of %s (%zu setting(s) x %d seed(s)), %lld numerical failure(s) -> %s\n", runs.size(), first.name().c_str(),
              combos.size(), per_setting, static_cast<long long>(doc["failed_runs"].get<std::int64_t>()), (out / files.front()).string().c_str());
}

SweepAxis parseSweepAxis(const std::string& text) {
  const auto bad = [&](const std::string& problem) {
    throw InputError(option("--vary"), problem, "\"" + text + "\"",
                     "KEY=V1,V2,... with TOML values, e.g. --vary numerics.cells_per_pixel=0.5,1,2 or --vary 'chemistry.ionic_strength=\"1 mM\",\"10 mM\"'");
  };
  const std::size_t eq = text.find('=');
  if (eq == std::string::npos) bad("no '=' between key and values");
  // The key is checked as --set checks it (CaseOverride::parse); the values are split here.
  SweepAxis axis{CaseOverride::parse(text.substr(0, eq) + "=").key, {}};
  std::string current;
  int depth = 0;
  bool quoted = false;
  const auto flush = [&] {
    std::size_t a = current.find_first_not_of(' '), b = current.find_last_not_of(' ');
    if (a == std::string::npos) bad("an empty value");
    axis.values.push_back(current.substr(a, b - a + 1));
    current.clear();
  };
  for (char ch : text.substr(eq + 1)) {
    if (ch == '"') quoted = !quoted;
    if (!quoted && (ch == '[' || ch == '{')) ++depth;
    if (!quoted && (ch == ']' || ch == '}')) --depth;
    if (ch == ',' && !quoted && depth == 0) {
      flush();
      continue;
    }
    current += ch;
  }
  if (quoted || depth != 0) bad("an unclosed quote or bracket");
  flush();
  for (std::size_t i = 0; i < axis.values.size(); ++i)
    for (std::size_t j = 0; j < i; ++j)
      if (axis.values[i] == axis.values[j]) bad("the value " + axis.values[i] + " is listed twice");
  return axis;
}

}  // namespace mmval::validate
