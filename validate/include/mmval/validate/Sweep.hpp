// A sweep (`mmval sweep`): one case run over a grid of key values and seeds, with the
// spread of every metric (per setting over seeds: mean, standard deviation,
// standard error; over settings: the band of the means and each key's effect).
// It is how a result gets its uncertainty: seeds for the stochastic part, a
// grid key for discretisation, unknown inputs (chemistry) for the band.
#pragma once
#include <map>
#include <string>
#include <vector>

#include <cstdint>
#include <nlohmann/json.hpp>

#include "mmval/core/CaseKind.hpp"

namespace mmval::validate {

/// One axis of a sweep: a case key and the TOML value texts it takes.
struct SweepAxis {
  std::string key;
  std::vector<std::string> values;
};

/// "KEY=V1,V2,..." split at top-level commas (commas inside quotes or brackets
/// belong to a value): `--vary 'chemistry.ionic_strength="1 mM","10 mM"'`.
/// InputError naming --vary on a missing key, '=' or value.
SweepAxis parseSweepAxis(const std::string& text);

/// Statistics of one metric over a sample (NaN entries are skipped; n counts the rest).
struct SampleStats {
  int n = 0;
  double mean = 0, sd = 0, se = 0, min = 0, max = 0;
  nlohmann::json toJson() const;
};
SampleStats sampleStats(const std::vector<double>& values);

/// What `mmval sweep` was asked to do (apps/SweepCommand.cpp fills it from the command line).
struct SweepOptions {
  std::string file, out;
  std::vector<std::string> vary, set, metrics;
  int seeds = 0;          ///< 0: the case's own seed only
  std::string seed_key;   ///< empty: the kind's one key named "*.seed"
  bool resume = false, quiet = false;
};

/// Runs the sweep: every run's case checked first, then runs/run-NNN/ one by one
/// (kept on resume when complete), then sweep.csv, sweep.json and sweep.svg in `out`,
/// and the table printed. InputError on a bad option or case; a run's numerical
/// failure is recorded in its row, not thrown.
void runSweep(const SweepOptions& options, const CaseKindRegistry& registry);

}  // namespace mmval::validate
