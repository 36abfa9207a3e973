// Case kinds: each capability (fluid solver, tracker, coupled simulation)
// registers the kinds of scene it can run, with their schema and a runner.
// `mmval run CASE` loads the case, dispatches on [case].kind and writes
// result.json. Registration is explicit (apps/main.cpp calls each library's
// register function), so nothing depends on static-initialisation order.
#pragma once
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mmval/core/Case.hpp"
#include "mmval/core/Schema.hpp"

namespace mmval {

/// What a runner gets: the folder to write into (a staging folder that is
/// renamed into place when the run completes) and run options.
struct RunContext {
  std::filesystem::path out_dir;
  bool quiet = false;   ///< no progress bars
  bool resume = false;  ///< out_dir may hold checkpoints of an interrupted run
  int threads = 0;     ///< 0: library default
};

/// What a runner returns. Metrics are SI values keyed by metric name; the
/// ones named in the case's [[acceptance]] are checked against it, the others
/// are reported as information (convert them with `units` for display).
struct RunOutput {
  std::map<std::string, double> metrics;             ///< SI
  std::map<std::string, std::string> units;          ///< display unit per metric ("1" default)
  nlohmann::json details = nlohmann::json::object(); ///< kind-specific (cells, iterations, ...)
  std::vector<std::string> files;                    ///< files written into out_dir
  /// Metrics the runner judged itself (e.g. simulation against an experiment
  /// measured in the same run); reported as they are.
  std::vector<MetricResult> evaluated;
};

struct CaseKind {
  std::string name;
  std::string summary;
  std::function<void(Schema&)> declare;  ///< adds the kind's keys
  std::function<void(Schema&)> metrics;  ///< declares the metrics its runner reports (Schema::metric)
  std::function<RunOutput(const Case&, const RunContext&)> run;
};

class CaseKindRegistry {
 public:
  void add(CaseKind kind);
  const CaseKind* find(std::string_view name) const;
  /// Gives an existing kind another runner (e.g. mmval's own solver for a kind
  /// whose schema a peer declared), keeping its schema.
  void replaceRunner(std::string_view name, std::function<RunOutput(const Case&, const RunContext&)> run);
  /// Sets the metric declarations of an existing kind (Schema::metric calls).
  void declareMetrics(std::string_view name, std::function<void(Schema&)> metrics);
  /// The kind's full schema (common [case] keys + the kind's keys).
  const Schema& schema(std::string_view name) const;
  std::vector<std::string> names() const;

 private:
  std::map<std::string, CaseKind, std::less<>> m_kinds;
  std::map<std::string, std::unique_ptr<Schema>, std::less<>> m_schemas;
  void rebuildSchemas();
};

}  // namespace mmval
