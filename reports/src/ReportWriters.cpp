// writeReport's table stages and the files written from them: metrics.json
// (runs, comparisons and tables together) and report.md.
#include <algorithm>
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

namespace {

std::string sweepNumber(const nlohmann::json& v, int digits = 4) { return v.is_number() ? fmt::format("{:.{}g}", v.get<double>(), digits) : std::string("-"); }

/// A discretisation part as two cells: the part with its method, and the two finest levels' difference with its seed SE.
std::array<std::string, 2> sweepPartCells(const nlohmann::json& p) {
  if (p.is_null()) return {"-", "-"};
  const std::string method = p["method"].get<std::string>();
  if (method == "none") return {"- (" + p["note"].get<std::string>() + ")", "-"};
  std::string part = sweepNumber(p["part"], 3) + " (" + method;
  if (p["observed_order"].is_number()) part += fmt::format(", order {:.2g}", p["observed_order"].get<double>());
  const auto& l = p["levels"];
  const std::string diff = fmt::format("{:g} vs {:g}: {} +- {}{}", l[0]["level"].get<double>(), l[1]["level"].get<double>(),
                                       p["difference"].is_number() ? fmt::format("{:+.3g}", p["difference"].get<double>()) : std::string("-"),
                                       sweepNumber(p["difference_se"], 2), p["resolved"].get<bool>() ? "" : " (within seed noise)");
  return {part + ")", diff};
}

}  // namespace

std::vector<std::pair<std::string, Table>> sweepTables(const ReportInput& input) {
  std::vector<std::pair<std::string, Table>> out;
  for (const auto& sw : input.sweeps) {
    const nlohmann::json& doc = sw.sweep;
    Table t;
    t.id = "sweep-table-" + fileId(sw.name);
    t.title = "Uncertainty of " + doc["case"]["name"].get<std::string>() + " (sweep " + sw.name + ")";
    const nlohmann::json d = doc.value("discretisation", nlohmann::json::object());
    const auto axisText = [&](const char* axis) {
      return d.contains(axis) && d[axis].is_object() ? d[axis]["key"].get<std::string>() + " (finer: " + d[axis].value("finer", std::string("?")) + ")" : std::string("none");
    };
    t.note = fmt::format("{} runs, {} seed(s) per setting. Grid axis: {}; step axis: {}. {}", doc.value("runs", 0), doc.value("seeds_per_setting", 0), axisText("grid"),
                         axisText("step"), d.value("rule", std::string()));
    t.header = {"metric", "setting", "value", "n", "seed SE", "grid part", "grid: two finest", "step part", "step: two finest", "combined", "verdict"};
    if (!doc.contains("uncertainty")) {
      t.note += " This sweep.json has no uncertainty block (written before mmval sweep computed one).";
      out.emplace_back(sweepPageKey(sw), t);
      continue;
    }
    // The metrics the sweep was asked to show first, then the rest by name.
    std::vector<std::string> order;
    for (const auto& m : doc.value("metrics_shown", nlohmann::json::array()))
      if (doc["uncertainty"].contains(m.get<std::string>())) order.push_back(m.get<std::string>());
    for (const auto& [name, u] : doc["uncertainty"].items())
      if (std::find(order.begin(), order.end(), name) == order.end()) order.push_back(name);
    // Every row is taken at the same finest grid and step: said once, in the note.
    const auto label = [](const nlohmann::json& o) {
      std::string text;
      for (const auto& [k, v] : o.items()) text += (text.empty() ? "" : ", ") + k + "=" + v.get<std::string>();
      return text.empty() ? std::string("-") : text;
    };
    bool other_axes = false;
    for (const auto& name : order) {
      const auto& settings = doc["uncertainty"][name]["settings"];
      if (!settings.empty() && t.note.find("Values at ") == std::string::npos) t.note = "Values at " + label(settings[0]["at"]) + ". " + t.note;
      for (const auto& e : settings) other_axes = other_axes || !e["setting"].empty();
    }
    for (const auto& name : order) {
      const auto& u = doc["uncertainty"][name];
      const std::string unit = u["unit"].get<std::string>();
      for (const auto& e : u["settings"]) {
        const auto grid = sweepPartCells(e["grid"]), step = sweepPartCells(e["step"]);
        t.rows.push_back({name, label(e["setting"]), sweepNumber(e["value"], 5) + (unit.empty() || unit == "1" ? "" : " " + unit),
                          std::to_string(e["n"].get<int>()), sweepNumber(e["seed_se"], 2), grid[0], grid[1], step[0], step[1], sweepNumber(e["combined"], 2),
                          e["verdict"].get<std::string>().empty() ? "-" : e["verdict"].get<std::string>()});
      }
    }
    if (!other_axes) {  // one setting: the column would only say "-"
      t.header.erase(t.header.begin() + 1);
      for (auto& row : t.rows) row.erase(row.begin() + 1);
    }
    out.emplace_back(sweepPageKey(sw), t);
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
  for (const auto& [key, t] : parts.sweep_tables) md += t.markdown();
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
