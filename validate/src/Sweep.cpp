#include "mmval/validate/Sweep.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <memory>
#include <optional>

#include <fmt/format.h>

#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/reports/Plot.hpp"
#include "mmval/validate/RunFolders.hpp"

namespace fs = std::filesystem;

namespace mmval::validate {

namespace {

constexpr int kMaxRuns = 1000;  ///< a guard against a mistyped product of axes

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

void readMetrics(const nlohmann::json& result, SweepRun& run, std::map<std::string, std::string>& units) {
  run.wall_seconds = result.at("cost").at("wall_seconds").get<double>();
  for (const auto& m : result.at("metrics")) {
    const std::string name = m.at("name").get<std::string>();
    if (run.metrics.count(name) != 0) continue;  // a metric checked twice: its value is the same
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

/// A value as people read it: a TOML string's text without its quotes.
std::string shown(const std::string& v) {
  return v.size() >= 2 && v.front() == '"' && v.back() == '"' ? v.substr(1, v.size() - 2) : v;
}

std::string number(double v) { return std::isfinite(v) ? fmt::format("{:.9g}", v) : std::string(); }

struct Tables {
  std::string csv, text;
  nlohmann::json json;
};

/// sweep.csv (one row per run), sweep.json (per setting over seeds, the band
/// over settings and each key's effect) and the terminal table.
Tables tabulate(const std::vector<SweepAxis>& axes, const std::vector<SweepRun>& runs, const std::map<std::string, std::string>& units,
                const std::vector<std::string>& chosen, int per_setting) {
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
  for (std::size_t g = 0; g * per_setting < runs.size(); ++g) {
    nlohmann::json setting = nlohmann::json::object(), stats = nlohmann::json::object();
    for (std::size_t a = 0; a < axes.size(); ++a) setting[axes[a].key] = shown(runs[g * per_setting].values[a]);
    for (const auto& n : names) {
      const SampleStats s = sampleStats(column(n, g * per_setting, per_setting));
      stats[n] = s.toJson();
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
  t.json = {{"groups", groups}, {"band", band}, {"effects", effects}};
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
  }
  return t;
}

/// The first chosen metric against the first axis, one line per other setting, error bars = standard error over seeds.
std::optional<std::string> plotSvg(const std::vector<SweepAxis>& axes, const nlohmann::json& groups, const std::string& metric,
                                   const std::string& unit) {
  if (axes.empty() || !reports::gnuplotAvailable()) return std::nullopt;
  reports::Plot p;
  p.title = "mmval sweep: " + metric + " (mean +- standard error over seeds)";
  p.xlabel = axes[0].key + " (";
  for (std::size_t i = 0; i < axes[0].values.size(); ++i) p.xlabel += (i ? ", " : "") + std::to_string(i) + ": " + shown(axes[0].values[i]);
  p.xlabel += ")";
  p.ylabel = metric + (unit.empty() || unit == "1" ? "" : " [" + unit + "]");
  std::map<std::string, reports::Series> lines;
  for (const auto& g : groups) {
    std::string rest;
    int index = 0;
    for (const auto& [k, v] : g["setting"].items()) {
      if (k == axes[0].key) {
        const auto& vals = axes[0].values;
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
  for (std::size_t i = 0; i < runs.size(); ++i) {
    SweepRun& r = runs[i];
    std::string label;
    for (const auto& ov : cases[i].overrides()) label += " " + ov.text();
    std::fprintf(stderr, "sweep [%zu/%zu] %s:%s\n", i + 1, runs.size(), r.folder.c_str(), label.c_str());
    const fs::path dir = out / "runs" / r.folder;
    std::optional<nlohmann::json> result = o.resume ? earlierRun(cases[i], dir) : std::nullopt;
    if (result) {
      std::fprintf(stderr, "      kept the complete earlier run (same case and settings)\n");
    } else {
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

  const int per_setting = std::max(seeds, 1);
  const Tables t = tabulate(axes, runs, units, o.metrics, per_setting);
  nlohmann::json doc = {{"schema", "mmval-sweep/1"}, {"case", {{"name", first.name()}, {"kind", first.kind()}, {"file", first.file().string()}}}};
  nlohmann::json ax = nlohmann::json::array();
  for (const auto& a : axes) ax.push_back({{"key", a.key}, {"values", a.values}});
  doc["axes"] = ax;
  doc["seed_key"] = seed_key.empty() ? nlohmann::json(nullptr) : nlohmann::json(seed_key);
  doc["seeds_per_setting"] = seeds;
  doc["set"] = o.set;
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
    if (auto svg = plotSvg(axes, doc["groups"], plotted, units.at(plotted))) {
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

nlohmann::json SampleStats::toJson() const {
  if (n == 0) return {{"n", 0}, {"mean", nullptr}, {"sd", nullptr}, {"se", nullptr}, {"min", nullptr}, {"max", nullptr}};
  return {{"n", n}, {"mean", mean}, {"sd", sd}, {"se", se}, {"min", min}, {"max", max}};
}

SampleStats sampleStats(const std::vector<double>& values) {
  SampleStats s;
  double sum = 0;
  s.min = std::numeric_limits<double>::infinity();
  s.max = -s.min;
  for (double v : values) {
    if (!std::isfinite(v)) continue;
    ++s.n;
    sum += v;
    s.min = std::min(s.min, v);
    s.max = std::max(s.max, v);
  }
  if (s.n == 0) return SampleStats{};
  s.mean = sum / s.n;
  double ss = 0;
  for (double v : values)
    if (std::isfinite(v)) ss += (v - s.mean) * (v - s.mean);
  s.sd = s.n > 1 ? std::sqrt(ss / (s.n - 1)) : 0.0;  // sample standard deviation
  s.se = s.sd / std::sqrt(static_cast<double>(s.n));
  return s;
}

}  // namespace mmval::validate
