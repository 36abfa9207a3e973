#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <set>

#include <fmt/format.h>

#include "ReportParts.hpp"
#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/DetailFields.hpp"
#include "mmval/reports/InputFiles.hpp"
#include "mmval/reports/Site.hpp"
#include "mmval/reports/Summary.hpp"

namespace fs = std::filesystem;

namespace mmval::reports::detail {

namespace {

/// One line of the summary: a run, or a compare folder that was not run as a case.
struct Entry {
  std::string name, kind, what, page;
  nlohmann::json run;      ///< result.json, or null
  nlohmann::json metrics;  ///< the metrics list
  const ComparisonInput* comparison = nullptr;
  int judged = 0, passed = 0;
  std::vector<std::string> failing;
  std::string status() const { return !failing.empty() ? "FAIL" : (judged > 0 ? "pass" : "info"); }
};

std::string passText(const nlohmann::json& m) { return m["pass"].is_null() ? "info" : (m["pass"].get<bool>() ? "pass" : "FAIL"); }

std::string number(const nlohmann::json& v) {
  if (v.is_number()) return fmt::format("{:.6g}", v.get<double>());
  return v.is_null() ? "-" : v.dump();
}

/// Unit text beside a number; "1" (dimensionless) reads "-".
std::string unitText(const nlohmann::json& m) {
  const std::string u = m.value("unit", "");
  return u.empty() || u == "1" ? "(-)" : u;
}

/// What a metric needs said beside it.
std::string metricNote(const nlohmann::json& m, const nlohmann::json& details) {
  const std::string name = metricOf(m);
  if (name == "speed_ks_statistic")
    return "D: the largest gap between the two cumulative distributions of per-step speeds, an effect size (0: identical, 1: disjoint). See the p-value's note.";
  if (name == "speed_ks_p_value") {
    std::string steps;
    if (const auto side = detailObject(details, DetailField::experiment)) {
      if (const auto n = detailInteger(*side, DetailField::experiment_steps))
        steps = fmt::format(" ({} steps on the first side)", *n);
      else if (const auto mobile = detailInteger(*side, DetailField::experiment_mobile))
        steps = fmt::format(" ({} mobile tracks on the first side)", *mobile);
    }
    return "Computed over every per-frame step" + steps +
           " as if the steps were independent. Steps along one track are strongly correlated, so the effective sample is closer to the number of tracks: "
           "the asymptotic p-value is far smaller than a correlation-respecting test would give and does not measure how different the distributions are. "
           "Read D (the largest gap between the two cumulative distributions) as the effect size; track_speed_ks_p_value, over one mean speed per track, "
           "is the test that respects the correlation.";
  }
  if (name == "track_speed_ks_p_value")
    return m.value("reason", std::string()) + ". Tracks of different particles are taken as independent; a particle the tracker lost and found again "
                                              "counts twice, which makes the p-value somewhat too small.";
  return m.value("reason", std::string());
}

std::string figureHtml(const Figure& f, const std::string& root) {
  std::string out = fmt::format("<figure id=\"fig-{}\">\n", htmlEscape(f.id));
  if (!f.svg.empty())
    out += f.svg;
  else
    out += fmt::format("<div><img class=\"fieldimg\" alt=\"{}\" src=\"{}figures/{}\">{}</div>", htmlEscape(f.caption), root, htmlEscape(f.image), f.colour_bar);
  out += "\n<figcaption>" + htmlEscape(f.caption);
  if (!f.data.empty()) out += fmt::format(" [data: <a href=\"{}{}\">{}</a>]", root, htmlEscape(f.data), htmlEscape(f.data_label));
  if (!f.image.empty()) out += fmt::format(" [<a href=\"{}figures/{}\">image</a>]", root, htmlEscape(f.image));
  return out + "</figcaption></figure>\n";
}

/// The case file of a run: case.file as given (relative to where the run was started), else
/// under the source tree.
fs::path caseFileOf(const nlohmann::json& r) {
  const std::string file = r["case"].value("file", "");
  if (file.empty()) return {};
  for (const fs::path& p : {fs::path(file), fs::path(MMVAL_REPORTS_SOURCE_DIR) / file})
    if (fs::is_regular_file(p)) return p;
  return {};
}

/// compare/ words its metrics for a real experiment ("experiment tracks"); on a page whose
/// tracked side is not real footage the word is replaced by what that side is.
std::string reword(std::string text, const std::string& tracked) {
  if (tracked.empty()) return text;
  for (const auto& [from, to] : std::vector<std::pair<std::string, std::string>>{{"experiment tracks", tracked}, {"experiment's", "tracked side's"}, {"experiment", "tracked side"}})
    for (std::size_t p = 0; (p = text.find(from, p)) != std::string::npos; p += to.size()) text.replace(p, from.size(), to);
  return text;
}

std::string metricsTable(const nlohmann::json& metrics, const nlohmann::json& details, const std::string& value_head, const std::string& reference_head,
                         const std::string& tracked = {}) {
  std::string out = fmt::format(
      "<table class=\"metrics\"><tr><th class=\"l\">metric</th><th>{}</th><th>{}</th><th>error</th><th>tolerance</th><th>result</th><th class=\"l\">source / note</th></tr>\n",
      htmlEscape(value_head), htmlEscape(reference_head));
  for (const auto& m : metrics) {
    const std::string pass = passText(m);
    const std::string ref = m["reference"].is_null() ? "-" : referenceText(m) + " " + unitText(m);
    std::string note = m.contains("source") && m["source"].is_string() ? linkDois(reword(m["source"].get<std::string>(), tracked)) : std::string();
    const std::string extra = reword(metricNote(m, details), tracked);
    if (!extra.empty()) note += (note.empty() ? "" : "<br>") + htmlEscape(extra);
    out += fmt::format("<tr class=\"{}\" id=\"metric-{}\"><td class=\"l\">{}</td><td>{} {}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"l note\">{}</td></tr>\n", pass,
                       htmlEscape(m["name"].get<std::string>()), htmlEscape(m["name"].get<std::string>()), number(m["value"]), htmlEscape(unitText(m)), htmlEscape(ref),
                       htmlEscape(errorText(m)), htmlEscape(m["tolerance"].is_null() ? "-" : m["tolerance"].get<std::string>()), pass, note);
  }
  return out + "</table>\n";
}


/// index.html's list of sweeps: each with its case, runs and how many metrics' verdicts say converged.
std::string sweepSummaryHtml(const ReportInput& input) {
  std::string html = "<h2 id=\"sweeps\">Sweeps</h2>\n<table id=\"sweep-list\"><tr><th class=\"l\">sweep</th><th class=\"l\">case</th><th>runs</th>"
                     "<th>seeds per setting</th><th class=\"l\">grid / step axis</th><th>metrics converged (of those with a verdict)</th></tr>\n";
  for (const auto& sw : input.sweeps) {
    const nlohmann::json& doc = sw.sweep;
    int judged = 0, converged = 0;
    const nlohmann::json uncertainty = doc.value("uncertainty", nlohmann::json::object());
    for (const auto& [name, u] : uncertainty.items())
      for (const auto& e : u["settings"])
        if (e["converged"].is_boolean()) {
          ++judged;
          converged += e["converged"].get<bool>();
        }
    const nlohmann::json d = doc.value("discretisation", nlohmann::json::object());
    const auto key = [&](const char* axis) { return d.contains(axis) && d[axis].is_object() ? d[axis]["key"].get<std::string>() : std::string("-"); };
    html += fmt::format("<tr><td class=\"l\"><a href=\"cases/{}\">{}</a></td><td class=\"l\">{}</td><td>{}</td><td>{}</td><td class=\"l\">{} / {}</td><td>{}</td></tr>\n",
                        htmlEscape(casePageName(sweepPageKey(sw))), htmlEscape(sw.name), htmlEscape(doc["case"]["name"].get<std::string>()), doc.value("runs", 0),
                        doc.value("seeds_per_setting", 0), htmlEscape(key("grid")), htmlEscape(key("step")),
                        judged == 0 ? std::string("no verdict asked") : fmt::format("{} of {}", converged, judged));
  }
  return html + "</table>\n";
}

/// A sweep's page: what was varied, the uncertainty table and the figures, with links to its files.
void writeSweepPage(const SweepInput& sw, const Parts& parts, const Provenance& prov, const fs::path& out) {
  const fs::path page_dir = out / "cases";
  const std::string key = sweepPageKey(sw);
  const nlohmann::json& doc = sw.sweep;
  std::string html = pageHead("Sweep " + sw.name + ": " + doc["case"]["name"].get<std::string>(), "../");
  html += provenanceHtml(prov);
  std::string axes;
  for (const auto& a : doc["axes"]) {
    std::string values;
    for (const auto& v : a.value("values", nlohmann::json::array())) values += (values.empty() ? "" : ", ") + v.get<std::string>();
    axes += (axes.empty() ? "" : "; ") + a["key"].get<std::string>() + " = " + values;
  }
  html += fmt::format("<p>Case {} run over {} ({} runs, {} seed(s) per setting, {} numerical failure(s)). The provenance above is the first run's.</p>\n",
                      htmlEscape(doc["case"]["name"].get<std::string>()), htmlEscape(axes.empty() ? std::string("no axis") : axes), doc.value("runs", 0),
                      doc.value("seeds_per_setting", 0), doc.value("failed_runs", 0));
  html += "<h2>Files</h2>\n<ul id=\"files\">\n";
  html += fmt::format("<li>sweep folder: <a href=\"{}/\">{}</a></li>\n", htmlEscape(relativeLink(sw.dir, page_dir)), htmlEscape(fs::absolute(sw.dir).lexically_normal().string()));
  for (const char* f : {"sweep.json", "sweep.csv", "sweep.svg"})
    if (fs::exists(sw.dir / f)) html += fmt::format("<li><a href=\"{}\">{}</a></li>\n", htmlEscape(relativeLink(sw.dir / f, page_dir)), f);
  html += "</ul>\n";
  for (const auto& [owner, t] : parts.sweep_tables)
    if (owner == key) html += t.html();
  bool any = false;
  for (const auto& f : parts.figures)
    if (f.owner == key) {
      if (!any) html += "<h2>Figures</h2>\n";
      any = true;
      html += figureHtml(f, "../");
    }
  writeFileAtomic(page_dir / casePageName(key), html + pageFoot());
}

}  // namespace

/// A path as an href: relative to the page's folder, with ' ', '#', '%' and '?' percent-encoded.
std::string relativeLink(const fs::path& target, const fs::path& from_dir) {
  const std::string path = fs::relative(fs::absolute(target), fs::absolute(from_dir)).generic_string();
  std::string out;
  for (char c : path) out += (c == ' ' || c == '#' || c == '%' || c == '?') ? fmt::format("%{:02X}", static_cast<unsigned char>(c)) : std::string(1, c);
  return out;
}

std::string pageKey(const nlohmann::json& run) {
  if (run.contains("run_dir") && run["run_dir"].is_string()) {
    fs::path dir = fs::path(run["run_dir"].get<std::string>()).lexically_normal();
    if (dir.filename().empty()) dir = dir.parent_path();
    const std::string folder = dir.filename().string();
    if (!folder.empty() && folder != "." && folder != "..") return folder;
  }
  return run["case"]["name"].get<std::string>();
}

std::string sweepPageKey(const SweepInput& sweep) { return "sweep-" + sweep.name; }

std::string casePageName(const std::string& name) {
  std::string out = name;
  for (char& c : out)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-')) c = '-';
  return out + ".html";
}

void writePages(const ReportInput& input, const Parts& parts, const fs::path& out) {
  fs::create_directories(out / "cases");
  std::vector<Entry> entries;
  auto judge = [](Entry& e) {
    for (const auto& m : e.metrics)
      if (m["pass"].is_boolean()) {
        ++e.judged;
        if (m["pass"].get<bool>())
          ++e.passed;
        else
          e.failing.push_back(m["name"].get<std::string>());
      }
  };
  for (const auto& r : input.summary.results) {
    Entry e;
    e.name = pageKey(r);
    e.kind = r["case"]["kind"].get<std::string>();
    if (const auto solver = detailString(resultDetails(r), DetailField::solver)) e.kind += ", " + *solver;
    if (e.name != r["case"]["name"].get<std::string>()) e.what = "case " + r["case"]["name"].get<std::string>() + ". ";
    e.what += r["case"].value("description", std::string());
    e.run = r;
    e.metrics = r["metrics"];
    for (const auto& c : input.comparisons)
      if (r.contains("run_dir") && fs::weakly_canonical(r["run_dir"].get<std::string>()) == fs::weakly_canonical(c.dir)) e.comparison = &c;
    if (e.comparison != nullptr || e.kind == "compare-tracks") {
      const ComparisonNames n = comparisonNames(r, input);
      e.kind = n.kind + " (" + e.kind + ")";
      e.what = n.reference + " against " + n.candidate;
    }
    judge(e);
    entries.push_back(std::move(e));
  }
  for (const auto& c : input.comparisons) {
    bool is_run = false;
    for (const auto& e : entries) is_run = is_run || e.comparison == &c;
    if (is_run) continue;
    Entry e;
    const ComparisonNames n = comparisonNames(nullptr, input);
    e.name = "compare-" + c.name;
    e.kind = n.kind;
    e.what = n.reference + " against " + n.candidate + " (folder " + c.dir.filename().string() + ")";
    e.metrics = c.metrics["metrics"];
    e.comparison = &c;
    judge(e);
    entries.push_back(std::move(e));
  }
  for (auto& e : entries) e.page = "cases/" + casePageName(e.name);
  // Failures first, then passes, then cases with informational metrics only; by name within.
  auto rank = [](const Entry& e) { return e.status() == "FAIL" ? 0 : (e.status() == "pass" ? 1 : 2); };
  std::stable_sort(entries.begin(), entries.end(), [&](const Entry& a, const Entry& b) { return rank(a) != rank(b) ? rank(a) < rank(b) : a.name < b.name; });

  const Provenance prov = provenanceOf(input);

  // Summary page.
  {
    int failing_cases = 0;
    for (const auto& e : entries) failing_cases += e.status() == "FAIL";
    std::string html = pageHead("mmval validation summary", "");
    html += provenanceHtml(prov);
    html += fmt::format("<p>{} case(s), <b>{} failing</b>, {}. Machine-readable: <a href=\"metrics.json\">metrics.json</a>, "
                        "<a href=\"report.md\">report.md</a>. The paper's tables and the figures across cases: <a href=\"paper.html\">paper.html</a>.</p>\n",
                        entries.size(), failing_cases, htmlEscape(input.summary.wallTimeText()));
    html += "<table id=\"cases\"><tr><th>result</th><th class=\"l\">case</th><th class=\"l\">kind</th><th>judged metrics passed</th><th class=\"l\">failing metrics</th>"
            "<th>wall time (s)</th><th class=\"l\">what it checks</th></tr>\n";
    for (const auto& e : entries) {
      std::string failing;
      for (const auto& f : e.failing)
        failing += fmt::format("{}<a href=\"{}#metric-{}\">{}</a>", failing.empty() ? "" : ", ", htmlEscape(e.page), htmlEscape(f), htmlEscape(f));
      html += fmt::format("<tr class=\"{}\"><td>{}</td><td class=\"l\"><a href=\"{}\">{}</a></td><td class=\"l\">{}</td><td>{} / {}</td><td class=\"l\">{}</td><td>{}</td><td class=\"l note\">{}</td></tr>\n",
                          e.status(), e.status(), htmlEscape(e.page), htmlEscape(e.name), htmlEscape(e.kind), e.passed, e.judged, failing.empty() ? "-" : failing,
                          e.run.is_null() ? "-" : fmt::format("{:.1f}", e.run["cost"]["wall_seconds"].get<double>()), htmlEscape(e.what));
    }
    html += "</table>\n";
    if (!input.sweeps.empty()) html += sweepSummaryHtml(input);
    html += "<h2 id=\"sources\">Sources of the references</h2>\n<ul>\n";
    std::map<std::string, std::set<std::string>> sources;
    for (const auto& e : entries)
      for (const auto& m : e.metrics)
        if (m.contains("source") && m["source"].is_string()) sources[m["source"].get<std::string>()].insert(e.name);
    for (const auto& [source, cases] : sources) {
      std::string used;
      for (const auto& c : cases) used += fmt::format("{}<a href=\"cases/{}\">{}</a>", used.empty() ? "" : ", ", htmlEscape(casePageName(c)), htmlEscape(c));
      html += "<li>" + linkDois(source) + " <span class=\"info\">(used by " + used + ")</span></li>\n";
    }
    html += "</ul>\n";
    writeFileAtomic(out / "index.html", html + pageFoot());
  }

  // Paper tables and cross-case figures.
  {
    std::string html = pageHead("Paper tables and cross-case figures", "");
    html += provenanceHtml(prov);
    if (parts.tables.empty()) html += "<p>No run of this report rebuilds a table of the paper.</p>\n";
    for (const auto& t : parts.tables) html += t.html();
    if (!parts.alignments.empty()) {
      html += "<h2>Alignment of tracked frames and simulation</h2>\n<ul id=\"alignment\">\n";
      for (const auto& a : parts.alignments) html += "<li>" + htmlEscape(a) + "</li>\n";
      html += "</ul>\n";
    }
    html += "<h2>Figures across cases</h2>\n";
    if (!parts.plots) html += "<p><b>gnuplot was not found: plots were left out.</b></p>\n";
    for (const auto& f : parts.figures)
      if (f.owner.empty()) html += figureHtml(f, "");
    writeFileAtomic(out / "paper.html", html + pageFoot());
  }

  for (const auto& sw : input.sweeps) writeSweepPage(sw, parts, sw.first_run.is_null() ? prov : provenanceOf(sw.first_run), out);

  // One page per case.
  for (const auto& e : entries) {
    const fs::path page_dir = out / "cases";
    std::string html = pageHead(e.name, "../");
    html += provenanceHtml(e.run.is_null() ? prov : provenanceOf(e.run));
    html += fmt::format("<p class=\"{}\">Result: <b>{}</b> ({} of {} judged metrics pass). Kind: {}.</p>\n", e.status(), e.status(), e.passed, e.judged, htmlEscape(e.kind));
    if (!e.what.empty()) html += "<p>" + htmlEscape(e.what) + "</p>\n";
    std::string value_head = "value", reference_head = "reference", tracked;
    const nlohmann::json& details = resultDetails(e.run);
    if (e.comparison != nullptr) {
      const ComparisonNames n = comparisonNames(e.run, input);
      html += fmt::format("<p><b>{}</b>: {}<br>value: {}<br>reference: {}</p>\n", htmlEscape(n.kind), htmlEscape(n.explanation), htmlEscape(n.candidate), htmlEscape(n.reference));
      value_head = "value: " + n.candidate;
      reference_head = "reference: " + n.reference;
      if (n.kind != "Experiment vs simulation") tracked = n.reference;
    }
    // Where its files are.
    html += "<h2>Files</h2>\n<ul id=\"files\">\n";
    const fs::path dir = !e.run.is_null() && e.run.contains("run_dir") ? fs::path(e.run["run_dir"].get<std::string>()) : (e.comparison ? e.comparison->dir : fs::path());
    if (!dir.empty() && fs::is_directory(dir)) {
      html += fmt::format("<li>run folder: <a href=\"{}/\">{}</a></li>\n", htmlEscape(relativeLink(dir, page_dir)), htmlEscape(fs::absolute(dir).lexically_normal().string()));
      std::vector<std::string> files;
      if (!e.run.is_null())
        for (const auto& f : e.run.value("files", nlohmann::json::array())) files.push_back(f.get<std::string>());
      else
        for (const auto& f : fs::directory_iterator(dir))
          if (f.is_regular_file()) files.push_back(f.path().filename().string());
      std::sort(files.begin(), files.end());
      for (const auto& f : files)
        if (fs::exists(dir / f)) html += fmt::format("<li><a href=\"{}\">{}</a></li>\n", htmlEscape(relativeLink(dir / f, page_dir)), htmlEscape(f));
      if (fs::exists(dir / "result.json")) html += fmt::format("<li><a href=\"{}\">result.json</a></li>\n", htmlEscape(relativeLink(dir / "result.json", page_dir)));
    }
    std::string case_text;
    if (!e.run.is_null()) {
      const fs::path case_file = caseFileOf(e.run);
      if (!case_file.empty()) {
        case_text = readInputFile(case_file);
        const std::string copy = fs::path(casePageName(e.name)).stem().string() + ".toml";
        writeFileAtomic(page_dir / copy, case_text);
        html += fmt::format("<li>case file: <a href=\"{}\">{}</a> (copy of {})</li>\n", htmlEscape(copy), htmlEscape(copy), htmlEscape(e.run["case"]["file"].get<std::string>()));
      } else {
        html += fmt::format("<li>case file: {} (not found; the resolved case below is what ran)</li>\n", htmlEscape(e.run["case"].value("file", std::string("not recorded"))));
      }
    }
    html += "</ul>\n<h2>Metrics</h2>\n" + metricsTable(e.metrics, details, value_head, reference_head, tracked);
    for (const auto& [owner, t] : parts.case_tables)
      if (owner == e.name) html += t.html();
    bool any = false;
    for (const auto& f : parts.figures)
      if (f.owner == e.name) {
        if (!any) html += "<h2>Figures</h2>\n";
        any = true;
        html += figureHtml(f, "../");
      }
    if (!case_text.empty()) html += "<h2>Case file</h2>\n<pre id=\"case-file\">" + htmlEscape(case_text) + "</pre>\n";
    if (!e.run.is_null() && e.run.contains("resolved_case"))
      html += "<details><summary>Resolved case (every key with its value as run)</summary><pre>" + htmlEscape(e.run["resolved_case"].dump(2)) + "</pre></details>\n";
    writeFileAtomic(page_dir / casePageName(e.name), html + pageFoot());
  }
}

}  // namespace mmval::reports::detail
