// Running a case: dispatch on its kind, evaluate its acceptance criteria,
// record provenance and cost, and write result.json atomically into a folder
// that only appears under its final name when the run is complete.
#pragma once
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mmval/core/Case.hpp"
#include "mmval/core/CaseKind.hpp"

namespace mmval {

struct RunSummary {
  std::string case_name;
  std::filesystem::path result_file;
  std::vector<MetricResult> metrics;
  double wall_seconds = 0.0;
  bool all_pass = true;  ///< every metric with a tolerance passed
  nlohmann::json result; ///< what result.json holds
};

struct RunOptions {
  bool quiet = false;
  bool resume = false;  ///< keep `<out>.partial` of an interrupted run for the runner's checkpoints
};

/// Runs `c` with its kind's runner into `out_dir` (staged as `out_dir.partial`).
RunSummary runCase(const Case& c, const CaseKindRegistry& registry, const std::filesystem::path& out_dir,
                   const RunOptions& options = {});

/// Same with an explicit runner (e.g. a peer solver for the same case).
RunSummary runCaseWith(const Case& c, const std::function<RunOutput(const Case&, const RunContext&)>& runner,
                       const std::filesystem::path& out_dir, const RunOptions& options = {});

/// Combines a runner's output with the case's acceptance entries: one result
/// per acceptance entry (a missing metric fails), then the informational ones.
std::vector<MetricResult> evaluateMetrics(const Case& c, const RunOutput& output);

/// Adds "observed_order" to each row of a resolution ladder (rows hold
/// "value"; levels are the resolutions, e.g. cells across): from three
/// successive levels, p = log((f2 - f1) / (f3 - f2)) / log(r).
void addObservedOrder(nlohmann::json& ladder, const std::vector<int>& levels);

/// `file` from the run of the case named by the string key `run_key` in the
/// same output folder as this run (validate's runs/): the way one case reads
/// another's outputs. Throws InputError naming the key when it is missing.
std::filesystem::path siblingRunFile(const Case& c, const RunContext& ctx, const std::string& run_key, const std::string& file);

/// The path in `key` when the case gives it, else `file` from the run named by
/// `key`_run (siblingRunFile). Throws InputError naming both keys when neither is given.
std::filesystem::path fileOrRunFile(const Case& c, const RunContext& ctx, const std::string& key, const std::string& file);

/// Peak resident memory of this process so far, bytes (getrusage).
long long peakMemoryBytes();

/// CPU seconds (user + system, every thread) this process has used so far; on several MPI
/// ranks, this rank's. A stage's cost on a shared machine, where wall time depends on the load.
double processCpuSeconds();

/// Versions, git hash, compiler, host: the provenance block of result.json.
nlohmann::json provenanceJson();

}  // namespace mmval
