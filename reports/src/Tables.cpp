#include "mmval/reports/Tables.hpp"
#include "mmval/reports/Site.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>

#include <fmt/format.h>

#include "mmval/reports/InputFiles.hpp"
#include "mmval/reports/Summary.hpp"

#include "mmval/core/DataPaths.hpp"
#include "mmval/core/DetailFields.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/ReferenceData.hpp"

namespace fs = std::filesystem;

namespace mmval::reports {

namespace {

std::string num(double v, int digits = 4) { return std::isfinite(v) ? fmt::format("{:.{}g}", v, digits) : "-"; }

bool isOpenFoam(const std::string& solver) { return solver.rfind("openfoam", 0) == 0 || solver.rfind("OpenFOAM", 0) == 0; }

/// One reference value (in the row's unit) or nothing.
std::optional<double> reference(const fs::path& dir, const std::string& file, const std::string& quantity, const AtMap& at) {
  if (dir.empty() || !fs::exists(dir / file)) return std::nullopt;
  try {
    const auto rows = loadReferenceFile(dir / file).find(quantity, at);
    if (rows.empty() || !rows.front()->value) return std::nullopt;
    return *rows.front()->value;
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

}  // namespace

std::string metricOf(const nlohmann::json& m) {
  if (m.contains("metric") && m["metric"].is_string()) return m["metric"].get<std::string>();
  return m.value("name", "");
}

std::optional<double> metricValue(const nlohmann::json& r, const std::string& name) {
  for (const auto& m : r.value("metrics", nlohmann::json::array()))
    if (metricOf(m) == name && m["value"].is_number()) return m["value"].get<double>();
  return std::nullopt;
}

bool paperCylinderSetup(const nlohmann::json& r) {
  for (const auto& m : r.value("metrics", nlohmann::json::array()))
    if (metricOf(m) == "c_D" && m.value("reference_setup", "") == kTable1Setup) return true;
  return false;
}

std::string Table::markdown() const {
  std::string out = fmt::format("\n## {}\n\n", title);
  if (!note.empty()) out += note + "\n\n";
  out += "|";
  for (const auto& h : header) out += " " + h + " |";
  out += "\n|";
  for (std::size_t i = 0; i < header.size(); ++i) out += "---|";
  out += "\n";
  for (const auto& r : rows) {
    out += "|";
    for (const auto& c : r) out += " " + c + " |";
    out += "\n";
  }
  return out;
}

std::string Table::html() const {
  std::string out = fmt::format("<h2>{}</h2>\n", htmlEscape(title));
  if (!note.empty()) out += "<p class=\"note\">" + linkDois(note) + "</p>\n";
  out += fmt::format("<table id=\"{}\"><tr>", htmlEscape(id));
  for (const auto& h : header) out += "<th>" + htmlEscape(h) + "</th>";
  out += "</tr>\n";
  for (const auto& r : rows) {
    out += "<tr>";
    for (const auto& c : r) out += "<td>" + htmlEscape(c) + "</td>";
    out += "</tr>\n";
  }
  return out + "</table>\n";
}

fs::path findReferenceData(const ReportInput& input) {
  for (const auto& r : input.summary.results) {
    const std::string file = r["case"].value("file", "");
    if (file.empty()) continue;
    const fs::path dir = fs::path(file).parent_path().parent_path() / "reference-data";
    if (fs::is_directory(dir)) return dir;
  }
  return referenceDataDirectory();  // mmval's own: installed, MMVAL_DATA_DIR or the source tree (DataPaths.hpp)
}

// The case says which Table 3 case it is (analysis.table3_case of particles-micromodel, written to
// details.table3_case).
std::string table3CaseOf(const nlohmann::json& details) {
  return detailString(details, DetailField::table3_case).value_or("");
}

std::optional<double> table3Reduction(const fs::path& dir, const std::string& roman) {
  if (roman.empty()) return std::nullopt;
  return reference(dir, "fines-cases-table3.toml", "permeability_reduction", {{"case", roman}});
}

std::optional<Table> cylinderDragTable(const ReportInput& input, const fs::path& dir) {
  // Our runs: Re -> (solver column -> C_d).
  std::map<double, std::map<std::string, double>> ours;
  bool any_openfoam = false;
  for (const auto& r : input.summary.results) {
    const auto re_run = detailNumber(resultDetails(r), DetailField::Re);
    if (!re_run) continue;
    // Only the paper's set-up (Schaefer-Turek runs also carry Re and c_D, in a channel).
    const auto cd = metricValue(r, "c_D");
    if (!cd || !paperCylinderSetup(r)) continue;
    double re = *re_run;
    for (double row : {10.0, 20.0, 40.0, 100.0})
      if (std::abs(re - row) <= 0.01 * row) re = row;
    const bool of = isOpenFoam(solverOf(r));
    any_openfoam = any_openfoam || of;
    ours[re][of ? "OpenFOAM" : "ours"] = *cd;
  }
  if (ours.empty()) return std::nullopt;
  Table t;
  t.id = "table1";
  t.title = "Table 1: drag coefficient against Re";
  t.note = dir.empty() ? "reference-data/ not found: the paper's columns are left out."
                       : "Paper columns from reference-data/cylinder-drag-paper-table1.toml and cylinder-drag-dennis-chang.toml; "
                         "'ours' is mmval's solver, 'OpenFOAM' the peer run of the same case file, where it ran. "
                         "Columns [66]-[69]: the models of references 66-69 of Elrahmani et al. (2022), Powder Technology 398, 117130, "
                         "doi:10.1016/j.powtec.2022.117130, as quoted in its Table 1 (their bibliographic entries are not verified here); "
                         "'paper model': that paper's own OpenFOAM set-up; Dennis & Chang (1970), doi:10.1017/S0022112070001428: unbounded steady flow. "
                         "All C_d are dimensionless (-).";
  t.header = {"Re", "[66]", "[67]", "[68]", "[69]", "paper model", "Dennis & Chang", "ours", "ours vs paper model"};
  if (any_openfoam) t.header.insert(t.header.end(), {"OpenFOAM", "OpenFOAM vs paper model"});
  std::map<double, std::map<std::string, double>> rows = ours;
  for (double re : {10.0, 20.0, 40.0, 100.0}) rows[re];  // the paper's rows even without our run
  for (const auto& [re, cols] : rows) {
    std::vector<std::string> row{num(re)};
    for (const char* col : {"[66]", "[67]", "[68]", "[69]", "this paper"}) {
      const auto v = reference(dir, "cylinder-drag-paper-table1.toml", "c_D", {{"Re", re}, {"column", std::string(col)}});
      row.push_back(v ? num(*v, 3) : "-");
    }
    const auto paper = reference(dir, "cylinder-drag-paper-table1.toml", "c_D", {{"Re", re}, {"column", std::string("this paper")}});
    const auto dc = reference(dir, "cylinder-drag-dennis-chang.toml", "c_D", {{"Re", re}});
    row.push_back(dc ? num(*dc, 4) : "-");
    auto cell = [&, &cols = cols](const char* who) {  // named capture: clang < 16 cannot capture a structured binding
      const auto it = cols.find(who);
      row.push_back(it != cols.end() ? num(it->second, 4) : "not run");
      row.push_back(it != cols.end() && paper ? fmt::format("{:+.1f} %", 100 * (it->second - *paper) / *paper) : "-");
    };
    cell("ours");
    if (any_openfoam) cell("OpenFOAM");
    t.rows.push_back(row);
  }
  return t;
}

std::optional<Table> chipTable(const ReportInput& input, const fs::path& dir) {
  std::vector<const nlohmann::json*> runs;
  // Image-permeability runs (a user's mask) and generated chips (chip-generator: the chip is
  // built to the measured k and porosity, so its column shows targets met, with the converged k).
  const auto generated = [](const nlohmann::json& r) { return r["case"].value("kind", "") == "chip-generator"; };
  for (const auto& r : input.summary.results)
    if ((r["case"].value("kind", "") == "image-permeability" && metricValue(r, "permeability")) ||
        (generated(r) && metricValue(r, "permeability_depth_averaged_extrapolated")))
      runs.push_back(&r);
  if (runs.empty()) return std::nullopt;
  Table t;
  t.id = "table2";
  t.title = "Table 2: chip permeability and porosity";
  t.note = "Measured (manufacturer) and the paper's model from reference-data/chip-permeability-table2.toml; one column per image-permeability run "
           "(its own mask and assumed pixel size: compare with the paper only when the mask is the paper's chip). Porosity: all pore pixels of the mask (connected in brackets). "
           "A generated chip (chip-generator) is built to the measured k and porosity: its column shows the targets met, not a validation; its k is the "
           "grid-converged (Richardson) value with its GCI.";
  t.header = {"quantity", "measured", "paper model"};
  for (const auto* r : runs)
    t.header.push_back("ours: " + (*r)["case"]["name"].get<std::string>() + (generated(*r) ? " (generated to the measured values)" : ""));
  std::vector<std::string> k{"permeability (D)"}, phi{"porosity"};
  for (const char* origin : {"measured", "paper model"}) {
    const auto kv = reference(dir, "chip-permeability-table2.toml", "permeability", {{"origin", std::string(origin)}});
    const auto pv = reference(dir, "chip-permeability-table2.toml", "porosity", {{"origin", std::string(origin)}});
    k.push_back(kv ? num(*kv, 3) : "-");
    phi.push_back(pv ? num(*pv, 3) : "-");
  }
  for (const auto* r : runs) {
    if (generated(*r)) {
      const auto gci = metricValue(*r, "permeability_depth_averaged_gci");
      k.push_back(num(*metricValue(*r, "permeability_depth_averaged_extrapolated"), 4) + (gci ? fmt::format(" (GCI {:.2g} %)", 100 * *gci) : ""));
      const auto connected = metricValue(*r, "porosity_connected");
      phi.push_back(connected ? num(*connected, 3) : "-");
      continue;
    }
    k.push_back(num(*metricValue(*r, "permeability"), 4));
    const auto total = metricValue(*r, "porosity_total"), connected = metricValue(*r, "porosity_connected");
    phi.push_back(total ? num(*total, 3) + (connected ? " (" + num(*connected, 3) + ")" : "") : (connected ? num(*connected, 3) : "-"));
  }
  t.rows = {k, phi};
  return t;
}

std::vector<std::string> table3TimeColumns(const nlohmann::json& run) {
  const auto t10 = metricValue(run, "time_to_10pct_reduction"), tc = metricValue(run, "time_to_clogging");
  return {t10 ? num(*t10, 4) : "-", tc ? num(*tc, 4) : "-"};
}

std::optional<Table> table3TrendsTable(const ReportInput& input, const fs::path& dir) {
  struct Case {
    double reduction = NAN, t10 = NAN;
  };
  std::map<std::string, Case> ours;
  for (const auto& r : input.summary.results) {
    const std::string roman = table3CaseOf(resultDetails(r));
    const auto red = metricValue(r, "permeability_reduction");
    if (roman.empty() || !red) continue;
    const auto t10 = metricValue(r, "time_to_10pct_reduction");
    ours[roman] = {*red, t10 ? *t10 : INFINITY};  // result.json holds metrics in their display unit (%)
  }
  const auto have = [&](std::initializer_list<const char*> keys) {
    for (const char* k : keys)
      if (!ours.count(k)) return false;
    return true;
  };
  const auto pct = [](double v) { return fmt::format("{:.3g} %", v); };
  const auto sec = [](double v) { return std::isfinite(v) ? fmt::format("{:.3g} s", v) : std::string("never"); };
  const auto paper = [&](const AtMap& at) { return reference(dir, "fines-cases-table3.toml", "permeability_reduction", at); };
  Table t;
  t.id = "table3-trends";
  t.title = "The paper's Table 3 trends, checked on our runs";
  t.note = "Reductions are 1 - k/k0 at the end of each run. The paper's particle-size results (Fig. 19) are at 0.24 cm/min; Table 3 lists the "
           "5 um-only (IV) and 10 um-only (V) cases at 0.024 cm/min, which is what our cases run.";
  t.header = {"trend", "paper", "ours", "ours follow"};
  if (have({"I", "II", "III"})) {
    const auto p1 = table3Reduction(dir, "I"), p2 = table3Reduction(dir, "II"), p3 = table3Reduction(dir, "III");
    const Case &a = ours["I"], &b = ours["II"], &c = ours["III"];
    t.rows.push_back({"more reduction at higher velocity: I (0.024) < II (0.048) < III (0.24 cm/min)",
                      p1 && p2 && p3 ? pct(*p1) + " < " + pct(*p2) + " < " + pct(*p3) : "-", pct(a.reduction) + " / " + pct(b.reduction) + " / " + pct(c.reduction),
                      a.reduction < b.reduction && b.reduction < c.reduction ? "yes" : "no"});
    t.rows.push_back({"bridging sooner at higher velocity: time to the first 10 % loss, I > II > III", "Fig. 18 (curves)",
                      sec(a.t10) + " / " + sec(b.t10) + " / " + sec(c.t10), a.t10 > b.t10 && b.t10 > c.t10 ? "yes" : "no"});
  }
  if (have({"IV", "V"})) {
    const auto p4 = paper({{"fines", std::string("5 um only")}}), p5 = paper({{"fines", std::string("10 um only")}});
    t.rows.push_back({"larger particles reduce more: 5 um only (IV) < 10 um only (V)", p4 && p5 ? pct(*p4) + " < " + pct(*p5) : "-",
                      pct(ours["IV"].reduction) + " / " + pct(ours["V"].reduction), ours["IV"].reduction < ours["V"].reduction ? "yes" : "no"});
    if (ours.count("I")) {
      const auto p3 = table3Reduction(dir, "III");
      t.rows.push_back({"polydisperse reduces most at one velocity: I >= IV and V", p3 && p4 && p5 ? pct(*p3) + " vs " + pct(*p4) + ", " + pct(*p5) : "-",
                        pct(ours["I"].reduction) + " vs " + pct(ours["IV"].reduction) + ", " + pct(ours["V"].reduction),
                        ours["I"].reduction >= ours["IV"].reduction && ours["I"].reduction >= ours["V"].reduction ? "yes" : "no"});
    }
  }
  if (t.rows.empty()) return std::nullopt;
  return t;
}

std::optional<Table> engineComparisonTable(const ReportInput& input) {
  Table t;
  t.id = "engines";
  t.title = "Overdamped engine against LIGGGHTS on a shared window of the scene";
  t.note = "Both engines start from the same particles on the same flow field and are compared at every output time: position differences "
           "(particles that left are skipped), capture events and the retained fraction of the window; no Brownian motion (LIGGGHTS has none), "
           "gravity raised as the window states so that particles reach the bottom plate. Wall times of one run, same machine.";
  t.header = {"case", "candidate", "window (s)", "particles", "RMS position diff (um)", "median final diff (nm)", "max diff (um)",
              "captured LIGGGHTS / candidate / both", "RMS capture time diff (s)", "retained LIGGGHTS / candidate", "wall LIGGGHTS / candidate (s)", "speed-up"};
  using F = DetailField;
  for (const auto& r : input.summary.results)
    for (const DetailRow& e : detailRows(resultDetails(r), F::engine_comparison)) {
      // A value the row lacks (or a non-finite one, written as null) reads "-".
      const auto value = [&e](F member, double scale) { return num(scale * detailNumber(e, member).value_or(NAN), 3); };
      const auto count = [&e](F member) {
        const auto n = detailInteger(e, member);
        return n ? std::to_string(*n) : std::string("-");
      };
      const double wl = detailNumber(e, F::engine_comparison_wall_seconds_reference).value_or(NAN);
      const double wc = detailNumber(e, F::engine_comparison_wall_seconds_candidate).value_or(NAN);
      t.rows.push_back({r["case"]["name"].get<std::string>(), detailString(e, F::engine_comparison_candidate).value_or("overdamped"),
                        value(F::engine_comparison_window_s, 1), count(F::engine_comparison_particles),
                        value(F::engine_comparison_rms_position_difference_m, 1e6), value(F::engine_comparison_median_final_difference_m, 1e9),
                        value(F::engine_comparison_max_position_difference_m, 1e6),
                        count(F::engine_comparison_captured_reference) + " / " + count(F::engine_comparison_captured_candidate) + " / " +
                            count(F::engine_comparison_captured_both),
                        value(F::engine_comparison_rms_capture_time_difference_s, 1),
                        value(F::engine_comparison_retained_fraction_reference, 1) + " / " + value(F::engine_comparison_retained_fraction_candidate, 1),
                        num(wl, 3) + " / " + num(wc, 3), wc > 0 ? num(wl / wc, 3) : "-"});
    }
  if (t.rows.empty()) return std::nullopt;
  return t;
}

std::map<std::string, std::vector<double>> readCsvColumns(const fs::path& file) {
  std::map<std::string, std::vector<double>> out;
  if (!fs::is_regular_file(file)) return out;
  std::istringstream in(readInputFile(file));
  std::string line;
  if (!std::getline(in, line)) return out;
  std::vector<std::string> names;
  {
    std::stringstream h(line);
    std::string cell;
    while (std::getline(h, cell, ',')) {
      while (!cell.empty() && std::isspace(static_cast<unsigned char>(cell.back()))) cell.pop_back();
      names.push_back(cell);
    }
  }
  int row = 1;
  while (std::getline(in, line)) {
    ++row;
    if (line.empty()) continue;
    std::stringstream s(line);
    std::string cell;
    for (std::size_t c = 0; c < names.size(); ++c) {
      if (!std::getline(s, cell, ',')) {
        // A row ending in ',' has an empty last cell, which std::getline does not report.
        if (c + 1 != names.size() || line.back() != ',')
          throw InputError({file.string(), row, static_cast<int>(c + 1), names[c]}, "row has too few columns", line, fmt::format("{} columns", names.size()));
        cell.clear();
      }
      double v;
      try {
        std::size_t used = 0;
        v = std::stod(cell, &used);
      } catch (const std::exception&) {
        // true/false columns (e.g. "resolves") read as 1/0; anything else is NaN.
        v = cell == "true" ? 1.0 : cell == "false" ? 0.0 : std::nan("");
      }
      out[names[c]].push_back(v);
    }
  }
  return out;
}

}  // namespace mmval::reports
