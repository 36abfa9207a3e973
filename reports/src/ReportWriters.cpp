// writeReport's table stages and the files written from them: metrics.json
// (runs, comparisons and tables together) and report.md.
#include <array>
#include <cmath>

#include <fmt/format.h>

#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Units.hpp"
#include "mmval/reports/Site.hpp"
#include "mmval/reports/Summary.hpp"
#include "ReportStages.hpp"

namespace fs = std::filesystem;

namespace mmval::reports::detail {

std::vector<Table> paperTables(const ReportInput& input, const fs::path& reference_dir, const std::vector<std::vector<std::string>>& reduction_rows) {
  std::vector<Table> tables;
  if (auto t = cylinderDragTable(input, reference_dir)) tables.push_back(*t);
  if (auto t = chipTable(input, reference_dir)) tables.push_back(*t);
  if (auto t = engineComparisonTable(input)) tables.push_back(*t);
  if (!reduction_rows.empty()) {
    Table t;
    t.id = "table3";
    t.title = "Permeability reduction (the paper's Table 3 cases)";
    t.note = "Runs that wrote permeability.csv; the paper's value when the case sets analysis.table3_case (I ... V).";
    t.header = {"run", "Table 3 case", "t end (s)", "k/k0 at end", "reduction", "paper", "difference", "first 10 % loss (s)", "clogged (s)"};
    t.rows = reduction_rows;
    tables.push_back(t);
  }
  if (auto t = table3TrendsTable(input, reference_dir)) tables.push_back(*t);
  return tables;
}

std::vector<std::pair<std::string, Table>> regionTables(const ReportInput& input) {
  std::vector<std::pair<std::string, Table>> out;
  auto cell = [](const nlohmann::json& v) { return v.is_number() ? fmt::format("{:.4g}", v.get<double>()) : std::string("-"); };
  for (const auto& c : input.comparisons) {
    if (!c.metrics.contains("regions")) continue;
    const auto& g = c.metrics["regions"];
    const ComparisonNames names = comparisonNames(runOf(input, c), input);
    Table t;
    t.id = "regions-" + c.name;
    t.title = "Mean speed per region";
    t.note = g.value("rule", "") + " Columns: " + names.reference + " (first) and " + names.candidate + " (second).";
    t.header = {"region", "tracked: " + names.reference + " (um/s)", names.candidate + " (um/s)", "relative difference", "steps (first)", "steps (second)"};
    for (const auto& keys : std::vector<std::array<std::string, 4>>{
             {"pore bodies", "pore_body_mean_speed_um_per_s", "pore_body_steps", "speed_pore_bodies_relative_difference"},
             {"throats", "throat_mean_speed_um_per_s", "throat_steps", "speed_throats_relative_difference"}}) {
      const std::string &label = keys[0], &key = keys[1], &steps = keys[2], &diff = keys[3];
      t.rows.push_back({label, cell(g["experiment"][key]), cell(g["simulation"][key]),
                        g.contains(diff) ? fmt::format("{:+.1f} %", 100 * g[diff].get<double>()) : "-", cell(g["experiment"][steps]),
                        cell(g["simulation"][steps])});
    }
    out.emplace_back(ownerOf(input, c), t);
  }
  return out;
}

std::vector<std::string> alignmentNotes(const ReportInput& input) {
  std::vector<std::string> out;
  for (const auto& c : input.comparisons) {
    if (!c.metrics.contains("alignment")) continue;
    const auto& a = c.metrics["alignment"];
    if (a.contains("dx_px"))
      out.push_back(fmt::format("{}: frame registered to the mask ({}): dx {:.3f} px ({:.3g} um), dy {:.3f} px ({:.3g} um), rotation {:.4f} deg, scale {:g}; "
                                "ECC correlation {:.4f}, RMS intensity residual {:.4f}, overlap {:.0f} %",
                                c.name, a.value("method", ""), a["dx_px"].get<double>(), a.value("dx_um", 0.0), a["dy_px"].get<double>(), a.value("dy_um", 0.0),
                                a["rotation_deg"].get<double>(), a.value("scale", 1.0), a["ecc_correlation"].get<double>(), a["rms_residual"].get<double>(),
                                100 * a.value("overlap_fraction", 0.0)));
    else if (a.is_object() && a.contains("method") && a["method"].is_string()) {
      // The method in words, then its parameters as "key value".
      std::string line = c.name + ": " + a["method"].get<std::string>();
      for (const auto& [key, value] : a.items())
        if (key != "method") line += ", " + key + " " + (value.is_number() ? fmt::format("{:.6g}", value.get<double>()) : value.is_string() ? value.get<std::string>() : value.dump());
      out.push_back(line);
    }
    else
      out.push_back(c.name + ": " + a.dump());
  }
  return out;
}

namespace {

/// A metric row of the report's metrics.json with the fields every row has (docs/outputs.md,
/// "metrics.json"): result.json's metric fields plus `case` and `solver`. Rows the report
/// derives itself, and rows of files written before `metric`, `label` and `dimension`
/// existed, get them here: the name as the metric, no label, the unit's SI dimension.
nlohmann::json uniformRow(nlohmann::json m, const std::string& case_name) {
  m["case"] = case_name;
  if (!m.contains("solver")) m["solver"] = "mmval";  // comparisons and the report's own figures
  if (!m.contains("metric")) m["metric"] = m["name"];
  if (!m.contains("label")) m["label"] = "";
  if (!m.contains("dimension")) {
    try {
      m["dimension"] = parseUnit(m.value("unit", "")).dim.siString();
    } catch (const UnitError&) {
      m["dimension"] = nullptr;  // free-text unit, as MetricResult::toJson writes it
    }
  }
  return m;
}

}  // namespace

void writeMetricsJson(const ReportInput& input, const Parts& parts, const nlohmann::json& extra_metrics, const fs::path& out) {
  nlohmann::json metrics = input.summary.metricsJson();
  for (auto& m : metrics["metrics"]) m = uniformRow(m, m["case"].get<std::string>());
  for (const auto& c : input.comparisons) {
    if (c.also_run) continue;  // a compare-tracks run: its rows came with its result.json above
    for (const auto& m : c.metrics["metrics"]) {
      metrics["metrics"].push_back(uniformRow(m, "compare:" + c.name));
      if (m["pass"].is_boolean() && !m["pass"].get<bool>()) metrics["all_pass"] = false;
    }
  }
  for (const auto& m : extra_metrics) metrics["metrics"].push_back(uniformRow(m, m.value("case", std::string())));
  metrics["tables"] = nlohmann::json::array();
  for (const auto& t : parts.tables) metrics["tables"].push_back({{"id", t.id}, {"title", t.title}, {"header", t.header}, {"rows", t.rows}});
  for (const auto& c : input.comparisons) {
    if (c.metrics.contains("alignment")) metrics["alignment"][c.name] = c.metrics["alignment"];
    if (c.metrics.contains("regions")) metrics["regions"][c.name] = c.metrics["regions"];
  }
  writeFileAtomic(out / "metrics.json", metrics.dump(2) + "\n");
}

void writeMarkdown(const ReportInput& input, const Parts& parts, const fs::path& out) {
  std::string md = input.summary.markdown();
  for (const auto& c : input.comparisons) {
    const ComparisonNames names = comparisonNames(runOf(input, c), input);
    md += fmt::format("\n## {}: {}\n\n{}\n\nvalue: {}; reference: {}.\n\n| metric | value | reference | error | tolerance | result |\n|---|---|---|---|---|---|\n",
                      names.kind, c.name, names.explanation, names.candidate, names.reference);
    for (const auto& m : c.metrics["metrics"])
      md += fmt::format("| {} | {:.4g} {} | {} {} | {} | {} | {} |\n", m["name"].get<std::string>(), m["value"].is_number() ? m["value"].get<double>() : std::nan(""),
                        m.value("unit", ""), referenceText(m), m["reference"].is_null() ? "" : m.value("unit", ""), errorText(m),
                        m["tolerance"].is_null() ? "-" : m["tolerance"].get<std::string>(), m["pass"].is_null() ? "info" : (m["pass"].get<bool>() ? "pass" : "FAIL"));
  }
  for (const auto& t : parts.tables) md += t.markdown();
  if (!parts.alignments.empty()) {
    md += "\n## Alignment of tracked frames and simulation\n\n";
    for (const auto& a : parts.alignments) md += "- " + a + "\n";
  }
  md += "\n## Figures\n\n";
  for (const auto& f : parts.figures)
    md += f.svg.empty() ? fmt::format("- {} (`figures/{}`)\n", f.caption, f.image) : fmt::format("- {} (`figures/{}.svg`, data `{}`)\n", f.caption, fileId(f.id), f.data);
  writeFileAtomic(out / "report.md", md);
}

}  // namespace mmval::reports::detail
