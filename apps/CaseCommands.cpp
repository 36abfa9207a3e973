#include "CaseCommands.hpp"

#include <cstdio>
#include <memory>

#include <fmt/format.h>

#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/core/Strings.hpp"
#include "mmval/reports/Summary.hpp"
#include "mmval/validate/Validation.hpp"
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
  std::string cases;  ///< empty: the example cases of mmval's data folder (validate::casesFolder)
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

/// Writes `text` to `file` unless something is there already (mmval init never overwrites).
void writeNewFile(const fs::path& file, const std::string& text) {
  std::error_code ec;
  if (fs::exists(fs::symlink_status(file, ec)))
    throw InputError({file.string(), 0, 0, "--out"}, "the file exists; mmval init does not overwrite files", {},
                     "a new file name, or remove the file first");
  writeFileAtomic(file, text);
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
    if (primaryRank()) printMetrics(s);  // under mpirun, one table, not one per rank
    if (!s.all_pass) throw MetricsFailed(fmt::format("case '{}': an acceptance metric failed (see {})", c.name(), s.result_file.string()));
  });

  // validate
  auto val_opts = std::make_shared<ValidateOptions>();
  CLI::App* val = app.add_subcommand("validate", "Run the default validation cases and write metrics.json, index.md and index.html");
  val->add_option("--out", val_opts->out, "Output folder")->capture_default_str();
  val->add_option("--cases", val_opts->cases,
                  "Folder of case files (default: the cases/ of mmval's data folder: $MMVAL_DATA_DIR, the installed share/mmval, or the source tree)");
  val->add_option("--tag", val_opts->tag,
                  "Run the cases carrying this tag in case.tags ('all' for every case); cases also tagged 'full' only with --full "
                  "(e.g. --tag paper: the paper's scenes at validation length; --tag paper --full: with the full-length ones)")
      ->capture_default_str();
  val->add_flag("--full", val_opts->full,
                "Also run the cases tagged 'full' (resolution ladders, full-length scenes): with the default tag every case tagged 'full', "
                "with --tag T those tagged both T and 'full'");
  val->add_flag("--resume", val_opts->resume,
                "Keep complete runs already in OUT whose case file is unchanged (same hash) and resume interrupted ones from their checkpoints");
  val->add_flag("--quiet", val_opts->quiet, "No progress output");
  val->callback([val_opts, &registry] {
    validate::ValidationOptions options;
    options.out = val_opts->out;
    options.cases = val_opts->cases;
    options.tag = val_opts->tag;
    options.full = val_opts->full;
    options.resume = val_opts->resume;
    options.quiet = val_opts->quiet;
    const validate::ValidationResult r = validate::runValidation(options, registry);
    std::fputs(r.summary.text().c_str(), stdout);
    std::printf("report: %d figure(s)\n", r.figures);
    std::printf("validation: %zu case(s), %d failing metric(s), %.1f s; summary in %s\n", r.cases, r.summary.failures(),
                r.summary.total_wall_seconds, (r.out / "index.html").string().c_str());
    if (r.summary.failures() > 0)
      throw MetricsFailed(fmt::format("{} metric(s) outside tolerance (see {})", r.summary.failures(), (r.out / "index.md").string()));
  });
}

}  // namespace mmval::app
