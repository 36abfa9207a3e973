// A sweep (`mmval sweep`): one case run over a grid of key values and seeds, with the
// spread of every metric (per setting over seeds: mean, standard deviation,
// standard error; over settings: the band of the means and each key's effect).
// It is how a result gets its uncertainty: seeds for the stochastic part, the
// grid and step axes (--grid, --step) for discretisation, unknown inputs
// (chemistry) for the band.
#pragma once
#include <limits>
#include <map>
#include <optional>
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

/// Which way a discretisation axis gets finer: larger values (cells per pixel)
/// or smaller ones (a step, a time step).
enum class Finer { larger, smaller };

/// One level of a discretisation ladder of a metric: the axis value as a
/// number, the metric's statistics over the seeds there and, when known, its
/// value per seed (seed order, the same for every level; NaN: that run has none).
struct LadderLevel {
  double value = 0;
  SampleStats stats;
  std::vector<double> by_seed;  ///< empty: not known (the levels are then taken as independent)
};

/// The standard error of mean(a) - mean(b) of two levels. When both have a
/// value for exactly the same seeds, at least two of them, the seeds are
/// paired: the sample standard deviation of the per-seed differences a_s - b_s
/// over sqrt(n) (`paired` true, `pairs` n). Otherwise the levels are taken as
/// independent: sqrt(se_a^2 + se_b^2), a level with fewer than two values
/// adding nothing (`paired` false, `pairs` the seeds with both values).
struct DifferenceError {
  double se = 0;
  bool paired = false;
  int pairs = 0;
};
DifferenceError differenceError(const LadderLevel& a, const LadderLevel& b);

/// The discretisation part of one axis for one metric: how far the finest
/// level's mean may be from the converged value.
///
/// The levels are sorted finest first; h is the axis value (Finer::smaller)
/// or its inverse (Finer::larger). `difference` is mean(finest) - mean(next),
/// its standard error from the seeds (differenceError: paired seeds when both
/// levels ran the same ones, else sqrt(se1^2 + se2^2)); `resolved` when
/// |difference| > 2 of them. With three levels whose two differences have one
/// sign, shrink towards the finest and are both resolved, the observed order p
/// and the Richardson estimate come from the three finest (ratios of h as they
/// are, the fixed-point iteration of Celik et al. 2008, J. Fluids Eng. 130,
/// 078001, eqs. 3-4): part = |difference| / (r21^p - 1) (method "richardson").
/// Otherwise part = |difference| (method "difference") and `note` says why.
/// Levels where the metric has no value (n = 0) are left out; fewer than two:
/// method "none", part NaN.
struct DiscretisationPart {
  std::string method = "none", note;
  std::vector<LadderLevel> levels;  ///< finest first
  double difference = std::numeric_limits<double>::quiet_NaN(), difference_se = std::numeric_limits<double>::quiet_NaN();
  std::string difference_se_rule;  ///< "paired" or "independent" (differenceError); empty with method "none"
  int paired_seeds = 0;            ///< seeds with a value at both of the two finest levels
  bool resolved = false;
  double observed_order = std::numeric_limits<double>::quiet_NaN(), extrapolated = std::numeric_limits<double>::quiet_NaN();
  double part = std::numeric_limits<double>::quiet_NaN(), part_se = std::numeric_limits<double>::quiet_NaN();
};
DiscretisationPart discretisationPart(std::vector<LadderLevel> levels, Finer finer);

/// The uncertainty of one metric at the finest grid and step: the seed part
/// (the standard error of the mean at that setting, NaN with fewer than two
/// values), the grid and step parts (DiscretisationPart; NaN when the sweep has
/// no such axis) and their root-sum-square, the parts that are NaN left out.
/// `converged` (with a tolerance): on every discretisation axis both |difference|
/// and part are within it; `converged_2se`: also part + 2 part_se.
struct MetricUncertainty {
  SampleStats finest;
  double seed_se = std::numeric_limits<double>::quiet_NaN();
  std::optional<DiscretisationPart> grid, step;
  double combined = std::numeric_limits<double>::quiet_NaN();
  std::optional<bool> converged, converged_2se;
  std::string verdict;
};
/// `tolerance`: NaN when no verdict was asked for (absolute, in the metric's unit).
MetricUncertainty metricUncertainty(const SampleStats& finest, std::optional<DiscretisationPart> grid, std::optional<DiscretisationPart> step,
                                    double tolerance);

/// What `mmval sweep` was asked to do (apps/SweepCommand.cpp fills it from the command line).
struct SweepOptions {
  std::string file, out;
  std::vector<std::string> vary, set, metrics;
  int seeds = 0;          ///< 0: the case's own seed only
  std::string seed_key;   ///< empty: the kind's one key named "*.seed"
  bool resume = false, quiet = false;
  /// Runs at once. 1: one after another in this process. More: each run is a child
  /// process `EXECUTABLE run CASE --out DIR --quiet --set ...` (outputs the same as with 1).
  int jobs = 1;
  std::string executable;  ///< the mmval the children run; empty: this process's own (/proc/self/exe)
  /// Discretisation axes: each one of the --vary keys with numeric values (empty: none).
  std::string grid_key, step_key;
  Finer grid_finer = Finer::larger, step_finer = Finer::smaller;
  /// Tolerances of the verdict, absolute in the metric's unit: "METRIC=VALUE", or
  /// "VALUE" for the metrics named in `metrics` (every metric when none is named)
  /// that have none of their own. None: no verdict.
  std::vector<std::string> converged_within;
};

/// Runs the sweep: every run's case checked first, then runs/run-NNN/ (kept on
/// resume when complete), one by one or `jobs` at a time in child processes, then
/// sweep.csv, sweep.json and sweep.svg in `out` (rows in run order either way), and
/// the table printed. sweep.json holds each metric's uncertainty per setting of the
/// axes that are neither grid nor step (metricUncertainty; docs/outputs.md).
/// InputError on a bad option or case; a run's numerical failure (in a child: exit
/// status 5) is recorded in its row, not thrown. A child that fails otherwise ends
/// the sweep, once the other running children have finished, with an error naming
/// its folder, its exit status and its log (runs/run-NNN.log): InputError for
/// status 1 or 2, std::runtime_error else.
void runSweep(const SweepOptions& options, const CaseKindRegistry& registry);

}  // namespace mmval::validate
