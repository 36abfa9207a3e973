#include "mmval/validate/Validation.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "mmval/core/DetailFields.hpp"
#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/openfoam/Kinds.hpp"
#include "mmval/openfoam/Peer.hpp"
#include "mmval/reports/Report.hpp"
#include "mmval/validate/CaseSelection.hpp"
#include "mmval/validate/RunFolders.hpp"

namespace fs = std::filesystem;

namespace mmval::validate {

namespace {

bool tagged(const Case& c, const std::string& tag) {
  const auto& tags = c.strings("case.tags");
  return std::find(tags.begin(), tags.end(), tag) != tags.end();
}

/// The runs of this validation a case reads its input from: the values of its `inputs.*_run` keys.
std::vector<std::string> inputRuns(const Case& c) {
  std::vector<std::string> runs;
  for (const KeyDecl& k : c.schema().keys())
    if (k.key.rfind("inputs.", 0) == 0 && k.key.size() > 4 && k.key.compare(k.key.size() - 4, 4, "_run") == 0 && c.has(k.key))
      runs.push_back(c.text(k.key));
  return runs;
}

/// mmval's run of one case: the complete earlier run when resuming, the case is unchanged and
/// no run it reads from was run again in this validation (`rerun`); else a new run.
nlohmann::json ownRun(const Case& c, const CaseKindRegistry& registry, const fs::path& run_dir, const ValidationOptions& options,
                      std::set<std::string>& rerun) {
  std::optional<nlohmann::json> done = options.resume ? earlierRun(c, run_dir) : std::nullopt;
  if (done) {
    for (const std::string& input : inputRuns(c))
      if (rerun.count(input) != 0) {
        std::fprintf(stderr, "      run again: its input run %s was run again\n", input.c_str());
        done.reset();
        break;
      }
  }
  if (done) {
    std::fprintf(stderr, "      kept the complete earlier run in %s (same case hash)\n", run_dir.string().c_str());
    return *done;
  }
  rerun.insert(c.name());
  // --resume also lets a runner pick up its own checkpoints in the staged folder.
  return runCase(c, registry, run_dir, {options.quiet, options.resume}).result;
}

/// The OpenFOAM peer's run of a case tagged "peer": an earlier complete peer
/// run when resuming, else a new run, else (no OpenFOAM) a "not run" result.
nlohmann::json peerRun(const Case& c, const fs::path& peer_dir, const ValidationOptions& options) {
  std::optional<nlohmann::json> done = options.resume ? earlierRun(c, peer_dir) : std::nullopt;
  if (done && detailString(resultDetails(*done), DetailField::status).value_or("") != "not run") return *done;
  if (!openfoam::detect().available) {
    const std::string reason = openfoam::detect().reason;
    std::fprintf(stderr, "      OpenFOAM peer not run for %s: %s\n", c.name().c_str(), reason.c_str());
    return peerNotRun(c, reason, peer_dir);
  }
  std::fprintf(stderr, "      %s through the OpenFOAM peer\n", c.name().c_str());
  const auto runner = [](const Case& cc, const RunContext& ctx) { return openfoam::runPeer(cc, ctx, {}); };
  return runCaseWith(c, runner, peer_dir, {options.quiet, false}).result;
}

}  // namespace

ValidationResult runValidation(const ValidationOptions& options, const CaseKindRegistry& registry) {
  const auto start = std::chrono::steady_clock::now();
  ValidationResult result;
  result.out = normaliseOutputPath(options.out);
  const fs::path& out = result.out;
  requireOwnedFolder(out);
  const fs::path cases_dir = casesFolder(options.cases);
  const auto files = casesTagged(cases_dir, options.tag, options.full, registry);
  if (files.empty()) {
    if (!options.full && fullOnlyTag(cases_dir, options.tag, registry))
      throw InputError({"(command line)", 0, 0, "--tag"}, "every case tagged '" + options.tag + "' is also tagged 'full' (run with --full)", options.tag,
                       "--tag " + options.tag + " --full, or a tag that cases without 'full' carry");
    throw InputError({cases_dir.string(), 0, 0, "case.tags"}, "no case carries the tag '" + options.tag + "'", {}, "at least one case to run");
  }
  std::fprintf(stderr, "validate: %zu case(s) from %s\n", files.size(), cases_dir.string().c_str());
  fs::create_directories(out / "runs");
  const FolderLock lock(out, out.string());
  writeOutputMarker(out);
  reports::Summary& summary = result.summary;
  std::set<std::string> rerun;  // cases run anew in this validation (not kept from an earlier one)
  for (std::size_t i = 0; i < files.size(); ++i) {
    const Case c = Case::load(files[i], registry);
    std::fprintf(stderr, "[%zu/%zu] %s (%s)\n", i + 1, files.size(), c.name().c_str(), c.kind().c_str());
    summary.results.push_back(ownRun(c, registry, out / "runs" / c.name(), options, rerun));
    if (tagged(c, "peer")) summary.results.push_back(peerRun(c, out / "runs" / (c.name() + "-openfoam"), options));
    summary.total_wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    // Partial summaries survive an interrupted validation. After the last case the report
    // below writes metrics.json and index.html (the same document with the comparisons and
    // tables added), so only index.md, which the report does not write, comes from here.
    if (i + 1 < files.size())
      writeSummary(out, summary);
    else
      writeFileAtomic(out / "index.md", summary.markdown());
    writeOutputMarker(out);
  }
  // The full report over every run folder; should it fail, the summary of every case still
  // stands in metrics.json and index.html.
  try {
    reports::ReportInput input = reports::collect({out});
    input.summary.total_wall_seconds = summary.total_wall_seconds;
    result.figures = reports::writeReport(input, out);
  } catch (...) {
    writeSummary(out, summary);
    throw;
  }
  writeOutputMarker(out);
  result.cases = files.size();
  return result;
}

void writeSummary(const fs::path& out, const reports::Summary& summary) {
  writeFileAtomic(out / "metrics.json", summary.metricsJson().dump(2) + "\n");
  writeFileAtomic(out / "index.md", summary.markdown());
  writeFileAtomic(out / "index.html", summary.html());
}

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

}  // namespace mmval::validate
