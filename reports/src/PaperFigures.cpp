#include "mmval/reports/PaperFigures.hpp"
#include "mmval/reports/Site.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <fmt/format.h>

#include "mmval/core/DetailFields.hpp"
#include "mmval/core/ReferenceData.hpp"
#include "mmval/reports/Tables.hpp"

namespace fs = std::filesystem;

namespace mmval::reports {

PermeabilityFigure permeabilityFigure(const ReportInput& input, const fs::path& refdir) {
  PermeabilityFigure out;
  std::vector<std::vector<std::string>>& reduction_rows = out.rows;
  nlohmann::json& extra_metrics = out.metrics;
  {
    Plot p{"Normalised permeability against time", "t (s)", "k / k0", false, false, {}, 720, 440};
    Series paper{"paper, Table 3 cases (end of injection)", {}, {}, "points pt 13 ps 1.6"};  // filled diamonds, as the labels
    for (const auto& r : input.summary.results) {
      if (!r.contains("run_dir")) continue;
      const fs::path file = fs::path(r["run_dir"].get<std::string>()) / "permeability.csv";
      if (!fs::exists(file)) continue;
      const auto cols = readCsvColumns(file);
      const std::string name = r["case"]["name"].get<std::string>();
      // The one schema of permeability.csv (mmval/core/OutputTables.hpp, docs/outputs.md "Tables").
      if (!cols.count("t_s") || !cols.count("k_over_k0")) {
        std::fprintf(stderr, "report: %s: no t_s and k_over_k0 columns (docs/outputs.md, Tables), left out of the permeability figure\n",
                     file.string().c_str());
        continue;
      }
      const std::vector<double>& ratio = cols.at("k_over_k0");
      const auto& t = cols.at("t_s");
      if (t.empty()) continue;
      p.series.push_back({name, t, ratio, "lines"});
      const std::string roman = table3CaseOf(resultDetails(r));
      const auto ref = table3Reduction(refdir, roman);
      const double final_ratio = ratio.back();
      if (ref) {
        paper.x.push_back(t.back());
        paper.y.push_back(1 - *ref / 100);
        p.labels.push_back({t.back(), 1 - *ref / 100, fmt::format("case {}: -{:g} %", roman, *ref)});
      }
      std::vector<std::string> row{name, roman.empty() ? "-" : roman, fmt::format("{:.4g}", t.back()), fmt::format("{:.4f}", final_ratio),
                                   fmt::format("{:.2f} %", 100 * (1 - final_ratio)), ref ? fmt::format("{:g} %", *ref) : "-",
                                   ref ? fmt::format("{:+.2f} points", 100 * (1 - final_ratio) - *ref) : "-"};
      for (auto& cell : table3TimeColumns(r)) row.push_back(std::move(cell));
      reduction_rows.push_back(row);
      nlohmann::json m{{"case", name}, {"name", "permeability_reduction"}, {"value", 100 * (1 - final_ratio)}, {"unit", "%"},
                       {"reference", ref ? nlohmann::json(*ref) : nlohmann::json(nullptr)}, {"error", ref ? nlohmann::json(100 * (1 - final_ratio) - *ref) : nlohmann::json(nullptr)},
                       {"error_kind", "absolute"}, {"tolerance", nullptr}, {"pass", nullptr},
                       {"reason", "1 - k/k0 at the end of the run; reference: the paper's Table 3 case named by the run, if any"}};
      if (ref) m["source"] = "reference-data/fines-cases-table3.toml, case " + roman;
      extra_metrics.push_back(m);
    }
    out.paper_points = static_cast<int>(paper.x.size());
    if (!paper.x.empty()) p.series.push_back(paper);
    if (!p.series.empty()) out.plot = p;
  }
  return out;
}


std::optional<Plot> retentionFigure(const ReportInput& input, const fs::path& refdir) {
  {
    Plot p{"Retained fraction against time", "t (s)", "retained fraction", false, false, {}, 720, 440};
    p.yrange = "[0:1]";
    double t_max = 0;
    for (const auto& r : input.summary.results) {
      if (!r.contains("run_dir")) continue;
      const fs::path file = fs::path(r["run_dir"].get<std::string>()) / "retention.csv";
      if (!fs::exists(file)) continue;
      const auto cols = readCsvColumns(file);
      // The one schema of retention.csv (mmval/core/OutputTables.hpp, docs/outputs.md "Tables"), every kind.
      if (!cols.count("t_s") || !cols.count("retained_fraction")) {
        std::fprintf(stderr, "report: %s: no t_s and retained_fraction columns (docs/outputs.md, Tables), left out of the retention figure\n",
                     file.string().c_str());
        continue;
      }
      Series s{r["case"]["name"].get<std::string>() + " (retained / injected)", cols.at("t_s"), cols.at("retained_fraction"), "lines"};
      if (!s.x.empty()) t_max = std::max(t_max, s.x.back());
      p.series.push_back(s);
    }
    for (const auto& c : input.comparisons) {
      const auto cols = readCsvColumns(c.dir / "retention_time.csv");
      if (!cols.count("t_s") || !cols.count("experiment") || !cols.count("simulation")) continue;
      if (!cols.at("t_s").empty()) t_max = std::max(t_max, cols.at("t_s").back());
      nlohmann::json run = nullptr;
      for (const auto& r : input.summary.results)
        if (r.contains("run_dir") && fs::weakly_canonical(r["run_dir"].get<std::string>()) == fs::weakly_canonical(c.dir)) run = r;
      const ComparisonNames names = comparisonNames(run, input);
      p.series.push_back({c.name + ": " + names.reference_short, cols.at("t_s"), cols.at("experiment"), "linespoints"});
      p.series.push_back({c.name + ": " + names.candidate_short, cols.at("t_s"), cols.at("simulation"), "linespoints"});
    }
    if (!p.series.empty() && t_max > 0) {
      // The micromodel's end-of-injection values (paper Sec. 3.3) as levels.
      auto level = [&](const char* origin) -> std::optional<double> {
        try {
          if (refdir.empty()) return std::nullopt;
          const auto rows = loadReferenceFile(refdir / "micromodel-experiment.toml").find("retention_fraction", {{"origin", std::string(origin)}});
          if (rows.empty() || !rows.front()->value) return std::nullopt;
          return *rows.front()->value / 100;
        } catch (const std::exception&) {
          return std::nullopt;
        }
      };
      if (const auto v = level("experiment")) p.series.push_back({fmt::format("paper: experiment {:g} %", 100 * *v), {0, t_max}, {*v, *v}, "lines dt 2"});
      if (const auto v = level("paper simulation")) p.series.push_back({fmt::format("paper: simulation {:g} %", 100 * *v), {0, t_max}, {*v, *v}, "lines dt 3"});
    }
    if (p.series.empty()) return std::nullopt;
    return p;
  }
}


}  // namespace mmval::reports
