#include "mmval/core/Run.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <string>
#include <cmath>
#include <cstdio>
#include <ctime>

#include <fmt/format.h>

#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/DataPaths.hpp"
#include "mmval/core/DetailFields.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/BuildInfo.hpp"

namespace mmval {

void addObservedOrder(nlohmann::json& ladder, const std::vector<int>& levels) {
  for (std::size_t i = 2; i < ladder.size() && i < levels.size(); ++i) {
    if (!ladder[i].contains("value") || !ladder[i - 1].contains("value") || !ladder[i - 2].contains("value")) continue;
    const double f1 = ladder[i - 2]["value"], f2 = ladder[i - 1]["value"], f3 = ladder[i]["value"];
    const double r = static_cast<double>(levels[i]) / levels[i - 1];
    if (std::abs(f3 - f2) > 0 && (f2 - f1) / (f3 - f2) > 0 && r > 1) ladder[i]["observed_order"] = std::log((f2 - f1) / (f3 - f2)) / std::log(r);
  }
}

long long peakMemoryBytes() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<long long>(usage.ru_maxrss) * 1024;  // Linux reports KiB
}

double processCpuSeconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

nlohmann::json provenanceJson() {
  char host[256] = {0};
  gethostname(host, sizeof host - 1);
  const std::time_t now = std::time(nullptr);
  char stamp[64];
  std::strftime(stamp, sizeof stamp, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&now));
  return {{"mmval_version", build::kVersion},
          {"git_hash", build::kGitHash},
          {"compiler", build::kCompiler},
          {"build_type", build::kBuildType},
          {"dependencies",
           {{"opencv", build::kOpenCV},
            {"eigen", build::kEigen},
            {"gsl", build::kGsl},
            {"petsc", build::kPetsc},
            {"mpi", build::kMpi},
            {"tomlplusplus", build::kTomlpp},
            {"nlohmann_json", build::kNlohmannJson}}},
          {"host", host},
          {"cores", static_cast<int>(sysconf(_SC_NPROCESSORS_ONLN))},
          {"finished_utc", stamp}};
}

std::vector<MetricResult> evaluateMetrics(const Case& c, const RunOutput& output) {
  std::vector<MetricResult> out;
  for (const auto& a : c.acceptance()) {
    auto it = output.metrics.find(a.metric);
    if (it == output.metrics.end()) {
      MetricResult m = evaluateMetric(a, std::nan(""));
      m.pass = false;
      m.reason = "the run produced no metric '" + a.metric + "'; " + a.reason;
      out.push_back(m);
    } else {
      out.push_back(evaluateMetric(a, it->second));
    }
  }
  for (const auto& m : output.evaluated) out.push_back(m);
  for (const auto& [name, value] : output.metrics) {
    if (c.acceptanceFor(name) != nullptr) continue;
    MetricResult m;
    m.name = name;
    auto u = output.units.find(name);
    const MetricDecl* declared = c.schema().findMetric(name);
    m.unit = u != output.units.end() ? u->second : declared != nullptr ? declared->unit : "1";
    m.value = value / parseUnit(m.unit).to_si;
    out.push_back(m);
  }
  return out;
}

RunSummary runCase(const Case& c, const CaseKindRegistry& registry, const std::filesystem::path& out_dir,
                   const RunOptions& options) {
  const CaseKind* kind = registry.find(c.kind());
  if (kind == nullptr) throw std::logic_error("no runner for kind '" + c.kind() + "'");
  return runCaseWith(c, kind->run, out_dir, options);
}

RunSummary runCaseWith(const Case& c, const std::function<RunOutput(const Case&, const RunContext&)>& runner,
                       const std::filesystem::path& out_dir, const RunOptions& options) {
  StagedDirectory staged(out_dir, options.resume);
  RunContext ctx;
  ctx.out_dir = staged.path();
  ctx.quiet = options.quiet;
  ctx.resume = options.resume;
  const auto start = std::chrono::steady_clock::now();
  const RunOutput output = runner(c, ctx);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  // Every metric a runner reports is declared by its kind (with its unit);
  // one that is not is a bug in mmval, flagged without losing the run.
  nlohmann::json undeclared = nlohmann::json::array();
  if (!c.schema().metrics().empty()) {
    for (const auto& [name, value] : output.metrics) {
      const MetricDecl* d = c.schema().findMetric(name);
      auto u = output.units.find(name);
      if (d == nullptr || (u != output.units.end() && !(parseUnit(u->second).dim == d->dim))) undeclared.push_back(name);
    }
  }
  if (!undeclared.empty())
    std::fprintf(stderr, "mmval: warning (a bug in mmval): kind '%s' reported metrics it does not declare, or in another dimension: %s\n",
                 c.kind().c_str(), undeclared.dump().c_str());

  RunSummary s;
  s.case_name = c.name();
  s.wall_seconds = wall;
  s.metrics = evaluateMetrics(c, output);
  nlohmann::json metrics = nlohmann::json::array();
  for (const auto& m : s.metrics) {
    metrics.push_back(m.toJson());
    if (m.pass.has_value() && !*m.pass) s.all_pass = false;
  }
  nlohmann::json case_json = {{"name", c.name()}, {"kind", c.kind()}, {"file", c.file().string()}, {"hash", c.hash()},
                               {"description", c.description()}};
  if (!c.overrides().empty()) {
    // `mmval run FILE --set ...`: what was set, so that the run can be repeated
    // (resolved_case holds the values in force, overrides included).
    nlohmann::json set = nlohmann::json::array();
    for (const auto& o : c.overrides()) set.push_back(o.text());
    case_json["overrides"] = set;
  }
  s.result = {{"schema", "mmval-result/1"},
              {"case", case_json},
              {"resolved_case", c.resolvedJson()},
              {"metrics", metrics},
              {"all_pass", s.all_pass},
              {"cost", {{"wall_seconds", wall}, {"peak_memory_bytes", peakMemoryBytes()}}},
              {"details", undeclared.empty() ? output.details : [&] {
                 nlohmann::json d = output.details;
                 setDetail(d, DetailField::undeclared_metrics, undeclared);
                 return d;
               }()},
              {"files", output.files},
              {"provenance", provenanceJson()}};
  // Under mpirun only rank 0 writes.
  if (primaryRank()) {
    writeFileAtomic(staged.path() / "result.json", s.result.dump(2) + "\n");
    staged.commit();
  }
  s.result_file = staged.finalPath() / "result.json";
  return s;
}

std::filesystem::path siblingRunFile(const Case& c, const RunContext& ctx, const std::string& run_key, const std::string& file) {
  const std::string& run = c.text(run_key);
  const std::filesystem::path runs = ctx.out_dir.parent_path();
  const std::filesystem::path f = runs / run / file;
  if (!pathExists(f))
    throw InputError(c.where(run_key), "no " + file + " from that run in " + runs.string(), run,
                     "the name of a case that `mmval validate` runs before this one");
  return f;
}

std::filesystem::path fileOrRunFile(const Case& c, const RunContext& ctx, const std::string& key, const std::string& file) {
  if (c.has(key)) return c.path(key);
  if (!c.has(key + "_run"))
    throw InputError(c.where(key), "missing", {}, key + " (a file) or " + key + "_run (a case run earlier in the same validation, for its " + file + ")");
  return siblingRunFile(c, ctx, key + "_run", file);
}

}  // namespace mmval
