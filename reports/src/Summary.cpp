#include "mmval/reports/Summary.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "mmval/core/DetailFields.hpp"

namespace mmval::reports {

namespace {

std::string number(const nlohmann::json& v) {
  if (v.is_null()) return "-";
  if (v.is_number()) return fmt::format("{:.6g}", v.get<double>());
  return v.dump();
}

/// The reference with the metric's unit, as the value has it ("1": dimensionless, no unit).
std::string referenceWithUnit(const nlohmann::json& m) {
  const std::string ref = referenceText(m), unit = m.value("unit", "");
  return ref == "-" || unit.empty() || unit == "1" ? ref : ref + " " + unit;
}

std::string passText(const nlohmann::json& m) {
  if (m["pass"].is_null()) return "info";
  return m["pass"].get<bool>() ? "pass" : "FAIL";
}

}  // namespace

std::string solverOf(const nlohmann::json& run) { return detailString(resultDetails(run), DetailField::solver).value_or("mmval"); }

std::string htmlEscape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

std::string referenceText(const nlohmann::json& m) {
  const auto& r = m["reference"];
  if (r.is_null()) return "-";
  if (r.is_array()) return fmt::format("[{:.6g}, {:.6g}]", r[0].get<double>(), r[1].get<double>());
  std::string out = number(r);
  if (m.contains("reference_uncertainty")) out += fmt::format(" ± {:.3g}", m["reference_uncertainty"].get<double>());
  return out;
}

std::string errorText(const nlohmann::json& m) {
  if (m["error"].is_null()) return "-";
  const double e = m["error"].get<double>();
  if (m.value("error_kind", "relative") == "relative") return fmt::format("{:.3g} %", 100.0 * e);
  const std::string unit = m.value("unit", "");
  return unit == "1" || unit.empty() ? fmt::format("{:.3g}", e) : fmt::format("{:.3g} {}", e, unit);
}

nlohmann::json Summary::metricsJson() const {
  nlohmann::json cases = nlohmann::json::array(), metrics = nlohmann::json::array();
  bool all = true;
  for (const auto& r : results) {
    const std::string name = r["case"]["name"];
    cases.push_back({{"name", name}, {"kind", r["case"]["kind"]}, {"hash", r["case"]["hash"]},
                     {"wall_seconds", r["cost"]["wall_seconds"]}, {"peak_memory_bytes", r["cost"]["peak_memory_bytes"]},
                     {"all_pass", r["all_pass"]}});
    for (auto m : r["metrics"]) {
      m["case"] = name;
      m["solver"] = solverOf(r);  // a peer run (OpenFOAM) has the same case name as mmval's own
      metrics.push_back(m);
    }
    all = all && r["all_pass"].get<bool>();
  }
  return {{"schema", "mmval-metrics/1"}, {"cases", cases}, {"metrics", metrics}, {"all_pass", all},
          {"total_wall_seconds", total_wall_seconds}};
}

int Summary::failures() const {
  int n = 0;
  for (const auto& r : results)
    for (const auto& m : r["metrics"])
      if (m["pass"].is_boolean() && !m["pass"].get<bool>()) ++n;
  return n;
}

double Summary::runsWallSeconds() const {
  double sum = 0;
  for (const auto& r : results)
    if (r.contains("cost") && r["cost"].contains("wall_seconds") && r["cost"]["wall_seconds"].is_number()) sum += r["cost"]["wall_seconds"].get<double>();
  return sum;
}

std::string Summary::wallTimeText() const {
  const double runs = runsWallSeconds();
  std::string out = fmt::format("total wall time {:.1f} s (the runs' own times added up)", runs);
  // A second of slack, or 2 %: the session also loads cases and writes the report.
  if (std::abs(total_wall_seconds - runs) > std::max(1.0, 0.02 * runs))
    out += fmt::format("; this session took {:.1f} s (runs kept from an earlier session count with their own time, or the session did more than run them)",
                       total_wall_seconds);
  return out;
}

std::string Summary::markdown() const {
  std::string out = "# mmval validation summary\n\n";
  out += fmt::format("{} case(s), {} failing metric(s), {}.\n\n", results.size(), failures(), wallTimeText());
  out += "| case | solver | metric | value | reference | error | tolerance | result |\n|---|---|---|---|---|---|---|---|\n";
  for (const auto& r : results)
    for (const auto& m : r["metrics"])
      out += fmt::format("| {} | {} | {} | {} {} | {} | {} | {} | {} |\n", r["case"]["name"].get<std::string>(), solverOf(r),
                         m["name"].get<std::string>(), number(m["value"]), m.value("unit", ""), referenceWithUnit(m),
                         errorText(m), m["tolerance"].is_null() ? "-" : m["tolerance"].get<std::string>(), passText(m));
  out += "\n## Cost and provenance\n\n| case | kind | wall time (s) | peak memory (MiB) | case hash |\n|---|---|---|---|---|\n";
  for (const auto& r : results)
    out += fmt::format("| {} | {} | {:.2f} | {:.0f} | `{}` |\n", r["case"]["name"].get<std::string>(),
                       r["case"]["kind"].get<std::string>(), r["cost"]["wall_seconds"].get<double>(),
                       r["cost"]["peak_memory_bytes"].get<double>() / 1048576.0, r["case"]["hash"].get<std::string>());
  if (!results.empty()) {
    const auto& p = results.front()["provenance"];
    out += fmt::format("\nmmval {} (git {}), {} {}, host {}.\n", p["mmval_version"].get<std::string>(),
                       p["git_hash"].get<std::string>(), p["compiler"].get<std::string>(),
                       p["build_type"].get<std::string>(), p["host"].get<std::string>());
  }
  out += "\n## Sources of the references\n\n";
  for (const auto& r : results)
    for (const auto& m : r["metrics"])
      if (m.contains("source")) out += fmt::format("- {} / {}: {}\n", r["case"]["name"].get<std::string>(), m["name"].get<std::string>(), m["source"].get<std::string>());
  return out;
}

std::string Summary::html() const {
  std::string out =
      "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>mmval validation summary</title>\n"
      "<style>body{font-family:sans-serif;margin:2em;max-width:70em}table{border-collapse:collapse}"
      "td,th{border:1px solid #bbb;padding:.25em .6em;text-align:right}td:first-child,td:nth-child(2),td:nth-child(3){text-align:left}"
      ".pass{background:#dfd}.FAIL{background:#fcc}.info{color:#666}</style></head><body>\n";
  out += fmt::format("<h1>mmval validation summary</h1>\n<p>{} case(s), <b>{}</b> failing metric(s), {}.</p>\n", results.size(), failures(),
                     htmlEscape(wallTimeText()));
  out += "<table id=\"summary\"><tr><th>case</th><th>solver</th><th>metric</th><th>value</th><th>unit</th><th>reference</th><th>error</th><th>tolerance</th><th>result</th></tr>\n";
  for (const auto& r : results)
    for (const auto& m : r["metrics"]) {
      const std::string pass = passText(m);
      out += fmt::format("<tr class=\"{}\"><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>\n",
                         pass, htmlEscape(r["case"]["name"].get<std::string>()), htmlEscape(solverOf(r)), htmlEscape(m["name"].get<std::string>()),
                         number(m["value"]), htmlEscape(m.value("unit", "")), htmlEscape(referenceWithUnit(m)),
                         htmlEscape(errorText(m)),
                         htmlEscape(m["tolerance"].is_null() ? "-" : m["tolerance"].get<std::string>()), pass);
    }
  out += "</table>\n<h2>Cost</h2>\n<table><tr><th>case</th><th>kind</th><th>wall time (s)</th><th>peak memory (MiB)</th><th>case hash</th></tr>\n";
  for (const auto& r : results)
    out += fmt::format("<tr><td>{}</td><td>{}</td><td>{:.2f}</td><td>{:.0f}</td><td>{}</td></tr>\n",
                       htmlEscape(r["case"]["name"].get<std::string>()), htmlEscape(r["case"]["kind"].get<std::string>()),
                       r["cost"]["wall_seconds"].get<double>(), r["cost"]["peak_memory_bytes"].get<double>() / 1048576.0,
                       r["case"]["hash"].get<std::string>());
  out += "</table>\n<h2>Sources</h2>\n<ul>\n";
  for (const auto& r : results)
    for (const auto& m : r["metrics"])
      if (m.contains("source"))
        out += fmt::format("<li>{} / {}: {}</li>\n", htmlEscape(r["case"]["name"].get<std::string>()),
                           htmlEscape(m["name"].get<std::string>()), htmlEscape(m["source"].get<std::string>()));
  out += "</ul>\n</body></html>\n";
  return out;
}

std::string Summary::text() const {
  std::string out = fmt::format("{:<24} {:<16} {:<20} {:>18} {:>22} {:>10} {:>10} {}\n", "case", "solver", "metric", "value",
                                "reference", "error", "tolerance", "result");
  for (const auto& r : results)
    for (const auto& m : r["metrics"])
      out += fmt::format("{:<24} {:<16} {:<20} {:>18} {:>22} {:>10} {:>10} {}\n", r["case"]["name"].get<std::string>(), solverOf(r),
                         m["name"].get<std::string>(), number(m["value"]) + " " + m.value("unit", ""), referenceWithUnit(m),
                         errorText(m), m["tolerance"].is_null() ? "-" : m["tolerance"].get<std::string>(), passText(m));
  return out;
}

}  // namespace mmval::reports
