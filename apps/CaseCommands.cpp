#include "CaseCommands.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <map>
#include <optional>

#include <fmt/format.h>

#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/DataPaths.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/core/Strings.hpp"
#include "mmval/openfoam/Kinds.hpp"
#include "mmval/openfoam/Peer.hpp"
#include "mmval/reports/Report.hpp"
#include "mmval/reports/Summary.hpp"
#include "CaseFolders.hpp"
#include "StarterCase.hpp"

namespace fs = std::filesystem;

namespace mmval::app {

namespace {

struct CaseCheckOptions {
  std::vector<std::string> files;
  bool resolved = false;
};

struct CaseDocOptions {
  std::string kind;
  std::string out;
};

struct InitOptions {
  std::string kind;
  std::string out;
};

struct RunOptionsCli {
  std::string file;
  std::string out;
  std::vector<std::string> set;  ///< KEY=VALUE overrides, in order
  bool quiet = false;
  bool resume = false;
};

struct ValidateOptions {
  std::string out = "out/validate";
  std::string cases;  ///< empty: the example cases of mmval's data folder (DataPaths.hpp)
  std::string tag = "default";
  bool full = false;
  bool resume = false;
  bool quiet = false;
};

void printMetrics(const RunSummary& s) {
  reports::Summary summary;
  summary.results.push_back(s.result);
  std::fputs(summary.text().c_str(), stdout);
  std::printf("%s: %s in %.2f s -> %s\n", s.case_name.c_str(), s.all_pass ? "all metrics pass" : "SOME METRICS FAIL",
              s.wall_seconds, s.result_file.string().c_str());
}

/// Case files under `dir` whose case.tags contain `tag` ("all" selects every case).
std::vector<fs::path> casesTagged(const fs::path& dir, const std::vector<std::string>& wanted, const CaseKindRegistry& registry) {
  if (!fs::is_directory(dir)) throw InputError({dir.string(), 0, 0, {}}, "cases folder not found", dir.string(), "a folder of *.toml case files (--cases)");
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().extension() == ".toml") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  // Comparisons read other cases' outputs, so they run after everything else.
  std::vector<fs::path> out, last;
  std::map<std::string, fs::path> by_name;  // run folders are named after the case: one case per name
  for (const auto& f : files) {
    const Case c = Case::load(f, registry);
    const auto& tags = c.strings("case.tags");
    const bool chosen = std::any_of(wanted.begin(), wanted.end(), [&](const std::string& tag) {
      return tag == "all" || std::find(tags.begin(), tags.end(), tag) != tags.end();
    });
    if (!chosen) continue;
    const auto [it, fresh] = by_name.emplace(c.name(), f);
    if (!fresh)
      throw InputError(c.where("case.name"), "two cases of this validation have the same name (their runs would overwrite each other)",
                       "\"" + c.name() + "\" in " + it->second.string() + " and " + f.string(), "a distinct case.name in each file");
    (c.kind() == "compare-tracks" ? last : out).push_back(f);
  }
  out.insert(out.end(), last.begin(), last.end());
  return out;
}

/// The cases folder validate reads: --cases when given, else the installed or
/// source tree's cases/ (DataPaths.hpp), else ./cases as before.
fs::path casesFolder(const std::string& given) {
  if (!given.empty()) return given;
  if (const fs::path dir = exampleCasesDirectory(); !dir.empty()) return dir;
  if (fs::is_directory("cases")) return "cases";
  throw InputError({"(command line)", 0, 0, "--cases"}, "no cases folder given and none found", dataDirectorySearched(),
                   "--cases DIR, or MMVAL_DATA_DIR set to a folder holding cases/ and reference-data/");
}

/// Writes `text` to `file` unless something is there already (mmval init never overwrites).
void writeNewFile(const fs::path& file, const std::string& text) {
  std::error_code ec;
  if (fs::exists(fs::symlink_status(file, ec)))
    throw InputError({file.string(), 0, 0, "--out"}, "the file exists; mmval init does not overwrite files", {},
                     "a new file name, or remove the file first");
  writeFileAtomic(file, text);
}

void writeSummary(const fs::path& out, const reports::Summary& summary) {
  writeFileAtomic(out / "metrics.json", summary.metricsJson().dump(2) + "\n");
  writeFileAtomic(out / "index.md", summary.markdown());
  writeFileAtomic(out / "index.html", summary.html());
}

/// The peer column of a case whose peer could not run: one informational
/// row that says why, so the report shows "not run" instead of a gap.
nlohmann::json peerNotRun(const Case& c, const std::string& reason, const fs::path& dir) {
  const nlohmann::json row = {{"name", "openfoam_peer"}, {"value", nullptr},      {"unit", ""},
                              {"reference", nullptr},    {"error", nullptr},      {"tolerance", nullptr},
                              {"pass", nullptr},         {"status", "not run"},   {"note", "not run: " + reason}};
  nlohmann::json doc = {{"schema", "mmval-result/1"},
                        {"case", {{"name", c.name() + "-openfoam"}, {"kind", c.kind()}, {"file", c.file().string()}, {"hash", c.hash()},
                                  {"description", c.description()}}},
                        {"metrics", nlohmann::json::array({row})},
                        {"all_pass", true},
                        {"cost", {{"wall_seconds", 0.0}, {"peak_memory_bytes", 0}}},
                        {"details", {{"solver", "OpenFOAM (not run)"}, {"status", "not run"}, {"reason", reason}}},
                        {"files", nlohmann::json::array()},
                        {"provenance", provenanceJson()}};
  StagedDirectory staged(dir);
  writeFileAtomic(staged.path() / "result.json", doc.dump(2) + "\n");
  staged.commit();
  return doc;
}

}  // namespace

void registerCaseCommands(CLI::App& app, const CaseKindRegistry& registry) {
  // case-check
  auto check_opts = std::make_shared<CaseCheckOptions>();
  CLI::App* check = app.add_subcommand("case-check", "Validate case files against their kind's schema and print the resolved case");
  check->add_option("files", check_opts->files, "Case files (TOML)")->required();
  check->add_flag("--resolved", check_opts->resolved, "Print the resolved case (defaults filled in) as JSON");
  check->callback([check_opts, &registry] {
    for (const auto& f : check_opts->files) {
      const Case c = Case::load(f, registry);
      std::printf("%s: ok (kind %s, case '%s', %zu acceptance criteria, hash %s)\n", f.c_str(), c.kind().c_str(),
                  c.name().c_str(), c.acceptance().size(), c.hash().c_str());
      if (check_opts->resolved) std::printf("%s\n", c.resolvedJson().dump(2).c_str());
    }
  });

  // case-doc
  auto doc_opts = std::make_shared<CaseDocOptions>();
  CLI::App* doc = app.add_subcommand("case-doc", "Print the reference of every case kind's keys (Markdown)");
  doc->add_option("kind", doc_opts->kind, "Only this kind");
  doc->add_option("--out", doc_opts->out, "Write to this file instead of stdout");
  doc->callback([doc_opts, &registry] {
    std::string text = "# mmval case files\n\nOne TOML file per scene. Quantities take units as strings (\"5 um\", "
                       "\"0.024 cm/min\", \"2.5 D\"); bare numbers are SI. Known units: " +
                       knownUnitSymbols() + ".\n\n";
    bool found = false;
    for (const auto& name : registry.names()) {
      if (!doc_opts->kind.empty() && name != doc_opts->kind) continue;
      text += registry.schema(name).markdown() + "\n";
      found = true;
    }
    if (!found && !doc_opts->kind.empty())
      throw InputError({"(command line)", 0, 0, "kind"}, "unknown case kind", doc_opts->kind, "one of the kinds listed by `mmval case-doc`");
    if (doc_opts->out.empty())
      std::fputs(text.c_str(), stdout);
    else
      writeFileAtomic(doc_opts->out, text);
  });

  // init
  auto init_opts = std::make_shared<InitOptions>();
  CLI::App* init = app.add_subcommand("init", "Print a commented starter case file of a kind (every key with its meaning, unit and default)");
  init->add_option("kind", init_opts->kind, "Case kind (`mmval case-doc` lists them)")->required();
  init->add_option("--out", init_opts->out, "Write to this new file instead of stdout (an existing file is refused)");
  init->callback([init_opts, &registry] {
    if (registry.find(init_opts->kind) == nullptr) {
      const auto names = registry.names();
      const std::string near = nearest(init_opts->kind, names);
      throw InputError({"(command line)", 0, 0, "kind"}, "unknown case kind" + (near.empty() ? std::string() : "; did you mean '" + near + "'?"),
                       init_opts->kind, "one of " + join(names, ", "));
    }
    const std::string text = starterCase(registry.schema(init_opts->kind));
    if (init_opts->out.empty())
      std::fputs(text.c_str(), stdout);
    else
      writeNewFile(init_opts->out, text);
  });

  // run
  auto run_opts = std::make_shared<RunOptionsCli>();
  CLI::App* run = app.add_subcommand("run", "Run one case file and write DIR/result.json (metrics against their references)");
  run->add_option("case", run_opts->file, "Case file (TOML)")->required();
  run->add_option("--out", run_opts->out, "Output folder (written as DIR.partial, renamed when complete)")->required();
  run->add_flag("--quiet", run_opts->quiet, "No progress output");
  run->add_flag("--resume", run_opts->resume, "Continue an interrupted run from DIR.partial");
  run->add_option("--set", run_opts->set,
                  "KEY=VALUE: set a case key as if the case file said KEY = VALUE (repeatable; recorded in result.json)")
      ->allow_extra_args(false);
  run->callback([run_opts, &registry] {
    std::vector<CaseOverride> overrides;
    for (const auto& s : run_opts->set) overrides.push_back(CaseOverride::parse(s));
    const Case c = Case::load(run_opts->file, registry, overrides);
    const RunSummary s = runCase(c, registry, run_opts->out, {run_opts->quiet, run_opts->resume});
    printMetrics(s);
    if (!s.all_pass) throw MetricsFailed(fmt::format("case '{}': an acceptance metric failed (see {})", c.name(), s.result_file.string()));
  });

  // validate
  auto val_opts = std::make_shared<ValidateOptions>();
  CLI::App* val = app.add_subcommand("validate", "Run the default validation cases and write metrics.json, index.md and index.html");
  val->add_option("--out", val_opts->out, "Output folder")->capture_default_str();
  val->add_option("--cases", val_opts->cases,
                  "Folder of case files (default: the cases/ of mmval's data folder: $MMVAL_DATA_DIR, the installed share/mmval, or the source tree)");
  val->add_option("--tag", val_opts->tag, "Run the cases carrying this tag in case.tags ('all' for every case)")->capture_default_str();
  val->add_flag("--full", val_opts->full, "Also run the cases tagged 'full' (resolution ladders, full-length scenes)");
  val->add_flag("--resume", val_opts->resume,
                "Keep complete runs already in OUT whose case file is unchanged (same hash) and resume interrupted ones from their checkpoints");
  val->add_flag("--quiet", val_opts->quiet, "No progress output");
  val->callback([val_opts, &registry] {
    const auto start = std::chrono::steady_clock::now();
    std::vector<std::string> wanted{val_opts->tag};
    if (val_opts->full) wanted.push_back("full");
    // The output folder is checked and locked before any case runs.
    const fs::path out = normaliseOutputPath(val_opts->out);
    requireOwnedFolder(out);
    const fs::path cases_dir = casesFolder(val_opts->cases);
    const auto files = casesTagged(cases_dir, wanted, registry);
    if (files.empty())
      throw InputError({cases_dir.string(), 0, 0, "case.tags"}, "no case carries the tag '" + val_opts->tag + "'", {}, "at least one case to run");
    std::fprintf(stderr, "validate: %zu case(s) from %s\n", files.size(), cases_dir.string().c_str());
    fs::create_directories(out / "runs");
    const FolderLock lock(out, out.string());
    writeOutputMarker(out);
    reports::Summary summary;
    for (std::size_t i = 0; i < files.size(); ++i) {
      const Case c = Case::load(files[i], registry);
      std::fprintf(stderr, "[%zu/%zu] %s (%s)\n", i + 1, files.size(), c.name().c_str(), c.kind().c_str());
      const fs::path run_dir = out / "runs" / c.name();
      std::optional<nlohmann::json> done = val_opts->resume ? earlierRun(c, run_dir) : std::nullopt;
      if (done) {
        std::fprintf(stderr, "      kept the complete earlier run in %s (same case hash)\n", run_dir.string().c_str());
        summary.results.push_back(*done);
      } else {
        // --resume also lets a runner pick up its own checkpoints in the staged folder.
        summary.results.push_back(runCase(c, registry, run_dir, {val_opts->quiet, val_opts->resume}).result);
      }
      // Cases tagged "peer" also run through OpenFOAM, side by side; a missing
      // OpenFOAM marks the peer "not run" instead of failing the validation.
      const auto& tags = c.strings("case.tags");
      if (std::find(tags.begin(), tags.end(), "peer") != tags.end()) {
        const fs::path peer_dir = out / "runs" / (c.name() + "-openfoam");
        std::optional<nlohmann::json> peer_done = val_opts->resume ? earlierRun(c, peer_dir) : std::nullopt;
        if (peer_done && peer_done->value("details", nlohmann::json::object()).value("status", "") != "not run") {
          summary.results.push_back(*peer_done);
        } else if (openfoam::detect().available) {
          std::fprintf(stderr, "      %s through the OpenFOAM peer\n", c.name().c_str());
          const RunSummary ps = runCaseWith(
              c, [](const Case& cc, const RunContext& ctx) { return openfoam::runPeer(cc, ctx, {}); }, peer_dir, {val_opts->quiet, false});
          summary.results.push_back(ps.result);
        } else {
          const std::string reason = openfoam::detect().reason;
          std::fprintf(stderr, "      OpenFOAM peer not run for %s: %s\n", c.name().c_str(), reason.c_str());
          summary.results.push_back(peerNotRun(c, reason, out / "runs" / (c.name() + "-openfoam")));
        }
      }
      summary.total_wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      writeSummary(out, summary);  // partial summaries survive an interrupted validation
      writeOutputMarker(out);
    }
    // The full report over every run folder.
    const reports::ReportInput input = reports::collect({out});
    reports::ReportInput with_time = input;
    with_time.summary.total_wall_seconds = summary.total_wall_seconds;
    const int figures = reports::writeReport(with_time, out);
    writeOutputMarker(out);
    std::fputs(summary.text().c_str(), stdout);
    std::printf("report: %d figure(s)\n", figures);
    std::printf("validation: %zu case(s), %d failing metric(s), %.1f s; summary in %s\n", files.size(), summary.failures(),
                summary.total_wall_seconds, (out / "index.html").string().c_str());
    if (summary.failures() > 0) throw MetricsFailed(fmt::format("{} metric(s) outside tolerance (see {})", summary.failures(), (out / "index.md").string()));
  });
}

}  // namespace mmval::app
