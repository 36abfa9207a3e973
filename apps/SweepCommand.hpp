// `mmval sweep`: one case run over a grid of key values and seeds, with the
// spread of every metric (per setting over seeds: mean, standard deviation,
// standard error; over settings: the band of the means and each key's effect).
// It is how a result gets its uncertainty: seeds for the stochastic part, a
// grid key for discretisation, unknown inputs (chemistry) for the band.
#pragma once
#include <map>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "mmval/core/CaseKind.hpp"

namespace mmval::app {

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

/// Adds the `sweep` subcommand; `registry` must outlive the app.
void registerSweepCommand(CLI::App& app, const CaseKindRegistry& registry);

}  // namespace mmval::app
