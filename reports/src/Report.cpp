// collect() finds runs and comparisons; writeReport() runs the stages of
// ReportStages.hpp in order; diffMetrics() compares two metrics documents.
#include "mmval/reports/Report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <map>
#include <vector>

#include <fmt/format.h>

#include "mmval/core/Error.hpp"
#include "mmval/reports/InputFiles.hpp"
#include "mmval/reports/JsonShape.hpp"
#include "mmval/reports/Plot.hpp"
#include "mmval/reports/Summary.hpp"
#include "mmval/reports/Tables.hpp"
#include "ReportStages.hpp"

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

/// A compare folder's metrics.json; other metrics.json files (a report's own) are not comparisons.
bool isComparison(const nlohmann::json& j) {
  return j.is_object() && j.contains("schema") && j["schema"].is_string() && j["schema"].get<std::string>() == "mmval-compare/1";
}

/// result.json of a sweep's first complete run (its provenance stands for the sweep's), or null.
nlohmann::json firstRunOfSweep(const fs::path& dir) {
  std::vector<fs::path> runs;
  if (fs::is_directory(dir / "runs"))
    for (const auto& e : fs::directory_iterator(dir / "runs"))
      if (fs::exists(e.path() / "result.json")) runs.push_back(e.path() / "result.json");
  if (runs.empty()) return nullptr;
  const fs::path first = *std::min_element(runs.begin(), runs.end());
  nlohmann::json j = readJsonFile(first);
  checkResultShape(j, first);
  return j;
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
        input.comparisons.push_back({d.filename().string(), d, j, fs::exists(d / "result.json")});
        found = true;
      }
    }
    // A sweep is one entry: its runs (dozens of one case) are read through its sweep.json, not listed one by one.
    const bool sweep = fs::exists(d / "sweep.json");
    if (sweep) {
      const auto j = readJsonFile(d / "sweep.json");
      checkSweepShape(j, d / "sweep.json");
      fs::path dir = d.lexically_normal();
      if (dir.filename().empty()) dir = dir.parent_path();
      input.sweeps.push_back({fs::absolute(dir).filename().string(), d, j, nullptr});
      input.sweeps.back().first_run = firstRunOfSweep(d);
      found = true;
    }
    for (const char* sub : {"runs", "compare"})
      if (fs::is_directory(d / sub) && !(sweep && std::string(sub) == "runs")) {
        std::vector<fs::path> children;
        for (const auto& e : fs::directory_iterator(d / sub))
          if (e.is_directory() && e.path().extension() != ".partial") children.push_back(e.path());
        std::sort(children.begin(), children.end());
        for (const auto& c : children) found = visit(c) || found;
      }
    return found;
  };
  for (const auto& d : dirs)
    if (!visit(d)) throw InputError({d.string(), 0, 0, {}}, "no result.json, compare metrics.json, sweep.json or runs/ found", {}, "a folder written by `mmval run`, `mmval compare`, `mmval validate` or `mmval sweep`");
  return input;
}

int writeReport(const ReportInput& input, const fs::path& out) {
  using namespace detail;
  const fs::path reference_dir = findReferenceData(input);
  Parts parts;
  parts.plots = gnuplotAvailable();

  // Figures, in the order the pages list them.
  FigureSink sink(out, parts.plots);
  crossCaseFigures(input, reference_dir, sink);
  forceHistoryFigures(input, sink);
  comparisonFigures(input, sink);
  const PaperFigureResults paper = paperFigures(input, reference_dir, sink);

  // Tables and notes.
  parts.tables = paperTables(input, reference_dir, paper.reduction_rows);
  parts.case_tables = regionTables(input);
  parts.alignments = alignmentNotes(input);
  parts.sweep_tables = sweepTables(input);
  sweepFigures(input, sink);

  physicsFigures(input, reference_dir, sink);
  runImages(input, sink);
  parts.figures = sink.figures();

  // Files: metrics.json, report.md, and the HTML pages (summary, paper.html, one per case).
  writeMetricsJson(input, parts, paper.metrics, out);
  writeMarkdown(input, parts, out);
  writePages(input, parts, out);
  return static_cast<int>(parts.figures.size());
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
  // compare's metrics.json and result.json name no case per metric. A case run by mmval and by
  // its OpenFOAM peer has its metrics twice under one case name: those keys also name the solver.
  auto keysOf = [](const nlohmann::json& doc) {
    std::map<std::string, int> count;
    auto plain = [](const nlohmann::json& m) { return m.value("case", std::string()) + "/" + m["name"].get<std::string>(); };
    for (const auto& m : doc["metrics"]) ++count[plain(m)];
    std::vector<std::string> keys;
    for (const auto& m : doc["metrics"]) {
      const std::string solver = m.contains("solver") && m["solver"].is_string() ? m["solver"].get<std::string>() : std::string();
      keys.push_back(count[plain(m)] > 1 && !solver.empty() ? m.value("case", std::string()) + " [" + solver + "]/" + m["name"].get<std::string>() : plain(m));
    }
    return keys;
  };
  const std::vector<std::string> keys_a = keysOf(a), keys_b = keysOf(b);
  std::map<std::string, nlohmann::json> before;
  for (std::size_t i = 0; i < keys_a.size(); ++i) before[keys_a[i]] = a["metrics"][i];
  std::string out = "| case/metric | before | after | change | tolerance | before result | after result |\n|---|---|---|---|---|---|---|\n";
  int n = 0;
  for (std::size_t i = 0; i < keys_b.size(); ++i) {
    const nlohmann::json& m = b["metrics"][i];
    const std::string& key = keys_b[i];
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
