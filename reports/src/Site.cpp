#include "mmval/reports/Site.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <limits>
#include <regex>
#include <set>
#include <sstream>

#include <fmt/format.h>

#include "mmval/core/DetailFields.hpp"
#include "mmval/core/VtkWriter.hpp"
#include "mmval/reports/InputFiles.hpp"
#include "mmval/reports/Summary.hpp"

namespace fs = std::filesystem;

namespace mmval::reports {

namespace {

std::string str(const nlohmann::json& j, const std::string& key) {
  return j.is_object() && j.contains(key) && j[key].is_string() && !j[key].get<std::string>().empty() ? j[key].get<std::string>() : std::string("not recorded");
}

std::string gnuplotVersion() {
  FILE* p = popen("gnuplot --version 2>/dev/null", "r");
  if (p == nullptr) return "not found";
  char buf[256] = {0};
  std::string out = std::fgets(buf, sizeof buf, p) != nullptr ? buf : "";
  pclose(p);
  while (!out.empty() && (out.back() == '\n' || out.back() == '\r')) out.pop_back();
  return out.empty() ? "not found" : out;
}

std::string nowUtc() {
  const std::time_t now = std::time(nullptr);
  char stamp[64];
  std::strftime(stamp, sizeof stamp, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&now));
  return stamp;
}

}  // namespace

Provenance provenanceOf(const nlohmann::json& result) {
  Provenance p;
  const nlohmann::json prov = result.value("provenance", nlohmann::json::object());
  const std::string hash = str(prov, "git_hash");
  if (hash != "not recorded") {
    const std::string suffix = "-dirty";
    const bool dirty = hash.size() > suffix.size() && hash.compare(hash.size() - suffix.size(), suffix.size(), suffix) == 0;
    p.git_hash = dirty ? hash.substr(0, hash.size() - suffix.size()) : hash;
    p.dirty = dirty ? "yes (uncommitted changes)" : "no";
  }
  p.run_date = str(prov, "finished_utc");
  p.host = str(prov, "host");
  p.compiler = str(prov, "compiler");
  p.build_type = str(prov, "build_type");
  p.mmval_version = str(prov, "mmval_version");
  const nlohmann::json deps = prov.value("dependencies", nlohmann::json::object());
  p.opencv = str(deps, "opencv");
  p.petsc = str(deps, "petsc");
  p.openfoam = str(deps, "openfoam");
  p.liggghts = str(deps, "liggghts");
  const nlohmann::json& details = resultDetails(result);
  const std::string solver = detailString(details, DetailField::solver).value_or("");
  if (p.openfoam == "not recorded" && solver.rfind("openfoam", 0) == 0) p.openfoam = solver + " (from the run's details.solver)";
  if (p.liggghts == "not recorded")
    if (const auto v = detailString(details, DetailField::liggghts_version)) p.liggghts = *v;
  p.report_date = nowUtc();
  p.gnuplot = gnuplotVersion();
  return p;
}

Provenance provenanceOf(const ReportInput& input) {
  if (input.summary.results.empty()) {
    // A report of sweeps only: the first sweep's first run stands for them.
    for (const auto& sw : input.sweeps)
      if (!sw.first_run.is_null()) return provenanceOf(sw.first_run);
    Provenance p;
    p.report_date = nowUtc();
    p.gnuplot = gnuplotVersion();
    return p;
  }
  Provenance p = provenanceOf(input.summary.results.front());
  for (const auto& r : input.summary.results) {
    const Provenance q = provenanceOf(r);
    if (q.git_hash != p.git_hash || q.host != p.host || q.dirty != p.dirty) p.mixed = true;
    // OpenFOAM and LIGGGHTS are recorded only by the runs that used them.
    if (p.openfoam == "not recorded") p.openfoam = q.openfoam;
    if (p.liggghts == "not recorded") p.liggghts = q.liggghts;
    if (q.run_date != "not recorded" && (p.run_date == "not recorded" || q.run_date > p.run_date)) p.run_date = q.run_date;
  }
  return p;
}

std::string provenanceHtml(const Provenance& p) {
  auto row = [](const std::string& k, const std::string& v) {
    return fmt::format("<tr><th>{}</th><td{}>{}</td></tr>", htmlEscape(k), v.rfind("not ", 0) == 0 ? " class=\"missing\"" : "", htmlEscape(v));
  };
  std::string out = "<details id=\"provenance\" class=\"provenance\" open><summary>Provenance</summary><table>";
  out += row("git commit", p.git_hash) + row("uncommitted changes (dirty)", p.dirty) + row("mmval", p.mmval_version);
  out += row("runs finished (UTC, latest)", p.run_date) + row("report built (UTC)", p.report_date) + row("host", p.host);
  out += row("compiler", p.compiler + (p.build_type != "not recorded" ? ", " + p.build_type : std::string()));
  out += row("OpenCV", p.opencv) + row("PETSc", p.petsc) + row("OpenFOAM", p.openfoam) + row("LIGGGHTS", p.liggghts) + row("gnuplot (report)", p.gnuplot);
  out += "</table>";
  if (p.mixed) out += "<p class=\"warn\">The runs of this report differ in commit, dirty flag or host: each case page shows its own.</p>";
  out += "</details>\n";
  return out;
}

std::string pageHead(const std::string& title, const std::string& root) {
  std::string out = fmt::format(
      "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title>\n"
      "<style>body{{font-family:sans-serif;margin:1.5em 2em;max-width:75em}}table{{border-collapse:collapse;margin:.5em 0}}"
      "td,th{{border:1px solid #bbb;padding:.2em .5em;text-align:right;vertical-align:top}}td.l,th.l{{text-align:left}}"
      ".pass{{background:#dfd}}.FAIL{{background:#fcc}}.info{{color:#555}}nav{{background:#eef;padding:.4em .8em;margin-bottom:1em}}nav a{{margin-right:1.2em}}"
      ".provenance{{font-size:90%;background:#f6f6f6;padding:.3em .8em;margin:.5em 0 1em}}.provenance th{{text-align:left}}.missing{{color:#a00}}"
      ".warn{{color:#a00}}.note{{font-size:92%;color:#333;max-width:60em}}figure{{margin:1em 0;border-top:1px solid #ddd;padding-top:.5em}}"
      "pre{{background:#f8f8f8;padding:.6em;overflow-x:auto;font-size:85%}}.cbar{{display:inline-block;vertical-align:top;margin-left:1em;font-size:90%}}"
      ".cbar .bar{{width:1.4em;height:16em;border:1px solid #555;background:linear-gradient(to top,#440154,#3b528b,#21918c,#5ec962,#fde725)}}"
      ".fieldimg{{max-width:80%;max-height:36em;vertical-align:top;image-rendering:pixelated}}</style></head><body>\n"
      "<nav><a href=\"{}index.html\">Summary</a><a href=\"{}paper.html\">Paper tables and cross-case figures</a><a href=\"{}index.html#sources\">Sources</a></nav>\n"
      "<h1>{}</h1>\n",
      htmlEscape(title), root, root, root, htmlEscape(title));
  return out;
}

std::string pageFoot() {
  return "<p id=\"image-status\"></p>\n<script>window.addEventListener('load',function(){var im=document.images,ok=0;"
         "for(var i=0;i<im.length;i++){if(im[i].complete&&im[i].naturalWidth>0)ok++;}"
         "document.getElementById('image-status').textContent='images loaded: '+ok+' of '+im.length;});</script>\n</body></html>\n";
}

std::string colourBarHtml(double lo, double hi, const std::string& unit, const std::string& label) {
  const bool known = std::isfinite(lo) && std::isfinite(hi);
  auto v = [&](double x) { return std::isfinite(x) ? fmt::format("{:.3g} {}", x, unit) : std::string("not recorded"); };
  return fmt::format(
      "<div class=\"cbar\"><div>{} ({})</div><div style=\"display:flex\"><div class=\"bar\"></div>"
      "<div style=\"display:flex;flex-direction:column;justify-content:space-between;height:16em;margin-left:.3em\"><span>{}</span><span>{}</span><span>{}</span></div></div>"
      "<div>grey: solid</div></div>",
      htmlEscape(label), htmlEscape(unit), htmlEscape(v(hi)), htmlEscape(known ? v(0.5 * (lo + hi)) : std::string()), htmlEscape(v(lo)));
}

double maxSpeedOfVtr(const fs::path& vtr) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (!fs::exists(vtr)) return nan;
  std::vector<double> u;
  int comps = 3;
  try {
    u = mmval::vtk::readArray(vtr, "U", &comps);
  } catch (const std::exception&) {
    return nan;
  }
  if (comps < 1) return nan;
  const auto n = static_cast<std::size_t>(comps);
  double best = 0;
  for (std::size_t k = 0; k + n <= u.size(); k += n) {
    double sum = 0;
    for (std::size_t c = 0; c < n; ++c) sum += u[k + c] * u[k + c];
    best = std::max(best, std::sqrt(sum));
  }
  return best;
}

double maxSpeedOnMidDepthPlane(const fs::path& vtr) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (!fs::exists(vtr)) return nan;
  try {
    const std::size_t nx = mmval::vtk::readArray(vtr, "x").size() - 1, ny = mmval::vtk::readArray(vtr, "y").size() - 1,
                      nz = mmval::vtk::readArray(vtr, "z").size() - 1;
    int comps = 3;
    const std::vector<double> u = mmval::vtk::readArray(vtr, "U", &comps);
    const std::vector<double> solid = mmval::vtk::readArray(vtr, "solid");
    const auto n = static_cast<std::size_t>(comps);
    if (nz < 2 || comps < 1 || u.size() != nx * ny * nz * n || solid.size() != nx * ny * nz) return nan;
    const std::size_t k = nz / 2;
    double best = 0;
    for (std::size_t cell = k * nx * ny; cell < (k + 1) * nx * ny; ++cell) {
      if (solid[cell] >= 0.5) continue;
      double sum = 0;
      for (std::size_t c = 0; c < n; ++c) sum += u[cell * n + c] * u[cell * n + c];
      best = std::max(best, std::sqrt(sum));
    }
    return best;
  } catch (const std::exception&) {
    return nan;
  }
}

std::string plotCsv(const Plot& plot) {
  auto q = [](const std::string& s) {
    std::string out = "\"";
    for (char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c);
    return out + "\"";
  };
  std::string out = fmt::format("# {}; x: {}; y: {}\nseries,x,y\n", plot.title, plot.xlabel, plot.ylabel);
  for (const auto& s : plot.series)
    for (std::size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i)
      if (std::isfinite(s.x[i]) && std::isfinite(s.y[i])) out += fmt::format("{},{:.10g},{:.10g}\n", q(s.name), s.x[i], s.y[i]);
  for (const auto& l : plot.labels) out += fmt::format("{},{:.10g},{:.10g}\n", q("label: " + l.text), l.x, l.y);
  return out;
}

namespace {

ComparisonNames comparisonNamesLong(const nlohmann::json& run, const ReportInput& input) {
  ComparisonNames n;
  if (run.is_null() || !run.contains("resolved_case") || !run["resolved_case"].is_object()) {
    n.kind = "Tracks vs simulation";
    n.reference = "tracks given as --experiment";
    n.candidate = "trajectories given as --simulation";
    n.explanation = "A folder written by `mmval compare`: where its tracks came from is not recorded, so it is not called an experiment here.";
    return n;
  }
  const auto& inputs = run["resolved_case"].value("inputs", nlohmann::json::object());
  auto kindOf = [&](const std::string& name) -> std::string {
    for (const auto& r : input.summary.results)
      if (r["case"]["name"] == name) return r["case"]["kind"].get<std::string>();
    return "";
  };
  auto runInput = [&](const std::string& name) -> const nlohmann::json* {
    for (const auto& r : input.summary.results)
      if (r["case"]["name"] == name) return &r;
    return nullptr;
  };
  const std::string sim = inputs.value("simulation_run", std::string());
  n.candidate = !sim.empty() ? "simulated trajectories of " + sim : "trajectories file " + inputs.value("simulation", std::string("(not recorded)"));
  const std::string exp_run = inputs.value("experiment_run", std::string());
  if (!exp_run.empty()) {
    const std::string kind = kindOf(exp_run);
    std::string source;
    if (const nlohmann::json* r = runInput(exp_run); r != nullptr && r->contains("resolved_case"))
      source = (*r)["resolved_case"].value("inputs", nlohmann::json::object()).value("trajectories_run", std::string());
    if (kind == "tracking-rendered" || kind == "tracking-synthetic" || !source.empty()) {
      n.kind = "Pipeline check";
      n.reference = "tracks of a rendered video of " + (source.empty() ? std::string("a simulation") : source) + " (run " + exp_run + ")";
      n.reference_short = "tracked, rendered video";
      n.candidate_short = "simulated";
      n.explanation = "Not an experiment: the simulation -> rendered video -> tracker -> comparator chain run on mmval's own output. "
                      "Differences measure what imaging and tracking do to each metric.";
      if (!source.empty() && source == sim) n.explanation += " Both sides come from the same simulation (" + sim + ").";
      return n;
    }
    n.kind = "Tracks vs simulation";
    n.reference = "tracks of run " + exp_run + " (" + (kind.empty() ? std::string("kind not in this report") : kind) + ")";
    n.explanation = "The tracks come from another run of this validation; their footage is not recorded as real.";
    return n;
  }
  n.kind = "Experiment vs simulation";
  n.reference = "tracks file " + inputs.value("experiment", std::string("(not recorded)")) + " (a user's footage)";
  n.explanation = "The experiment side is a user's tracks file (inputs.experiment).";
  return n;
}

}  // namespace

ComparisonNames comparisonNames(const nlohmann::json& run, const ReportInput& input) {
  ComparisonNames n = comparisonNamesLong(run, input);
  if (n.reference_short.empty()) n.reference_short = n.kind == "Experiment vs simulation" ? "experiment (tracked video)" : "tracks";
  if (n.candidate_short.empty()) n.candidate_short = "simulated";
  return n;
}

std::string linkDois(const std::string& text) {
  static const std::regex doi(R"((?:https?://doi\.org/|doi:\s*)(10\.\d{4,9}/[^\s,;)]+[^\s,;).]))");
  std::string out;
  std::size_t last = 0;
  for (auto it = std::sregex_iterator(text.begin(), text.end(), doi); it != std::sregex_iterator(); ++it) {
    const auto& m = *it;
    out += htmlEscape(text.substr(last, m.position(0) - last));
    const std::string id = m[1].str();
    out += fmt::format("<a href=\"https://doi.org/{}\">doi:{}</a>", htmlEscape(id), htmlEscape(id));
    last = m.position(0) + m.length(0);
  }
  return out + htmlEscape(text.substr(last));
}

std::vector<std::string> brokenLinks(const fs::path& dir) {
  std::vector<std::string> broken;
  static const std::regex link(R"((?:href|src)="([^"]*)\")");
  static const std::regex id(R"(\bid="([^"]*)\")");
  auto unescape = [](std::string s) {
    for (const auto& [from, to] : std::vector<std::pair<std::string, std::string>>{{"&quot;", "\""}, {"&lt;", "<"}, {"&gt;", ">"}, {"&amp;", "&"}})
      for (std::size_t p = 0; (p = s.find(from, p)) != std::string::npos; p += to.size()) s.replace(p, from.size(), to);
    return s;
  };
  auto idsOf = [&](const fs::path& page) {
    std::set<std::string> ids;
    std::ifstream in(page);
    std::stringstream b;
    b << in.rdbuf();
    const std::string text = b.str();
    for (auto it = std::sregex_iterator(text.begin(), text.end(), id); it != std::sregex_iterator(); ++it) ids.insert(unescape((*it)[1].str()));
    return ids;
  };
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (!e.is_regular_file() || e.path().extension() != ".html") continue;
    std::ifstream in(e.path());
    std::stringstream b;
    b << in.rdbuf();
    const std::string text = b.str();
    const std::string page = fs::relative(e.path(), dir).string();
    for (auto it = std::sregex_iterator(text.begin(), text.end(), link); it != std::sregex_iterator(); ++it) {
      const std::string target = unescape((*it)[1].str());
      if (target.rfind("data:", 0) == 0 || target.rfind("http://", 0) == 0 || target.rfind("https://", 0) == 0 || target.rfind("mailto:", 0) == 0) continue;
      if (target.empty()) {
        broken.push_back(page + ": (empty link)");
        continue;
      }
      const auto hash = target.find('#');
      std::string file = target.substr(0, hash);
      const std::string fragment = hash == std::string::npos ? std::string() : target.substr(hash + 1);
      // Percent-encoded spaces and the like.
      for (std::size_t p = 0; (p = file.find('%', p)) != std::string::npos;) {
        if (p + 2 < file.size() && std::isxdigit(static_cast<unsigned char>(file[p + 1])) && std::isxdigit(static_cast<unsigned char>(file[p + 2])))
          file.replace(p, 3, std::string(1, static_cast<char>(std::stoi(file.substr(p + 1, 2), nullptr, 16))));
        ++p;
      }
      const fs::path resolved = file.empty() ? e.path() : e.path().parent_path() / file;
      if (!fs::exists(resolved)) {
        broken.push_back(page + ": " + target);
        continue;
      }
      if (!fragment.empty()) {
        if (resolved.extension() != ".html" || idsOf(resolved).count(fragment) == 0) broken.push_back(page + ": " + target + " (no such anchor)");
      }
    }
  }
  return broken;
}

}  // namespace mmval::reports

