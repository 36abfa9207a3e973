// Experiment vs simulation, metric by metric, on the shared tracks schema.
#pragma once
#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mmval/compare/Regions.hpp"
#include "mmval/compare/Retention.hpp"
#include "mmval/tracking/TrackMetrics.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/Tracks.hpp"

namespace mmval::compare {

using tracking::TrackOptions;
using tracking::TrackStats;
using tracking::TimeSeries;

/// The rest rule compareTracks applies to both files before it measures speeds and spreads
/// (labelRests). Defaults: the tracker's analysis.stuck_window and stuck_distance
/// (tracking::TrackOptions); window 0: off, the files' own labels decide.
struct RestRule {
  double window = TrackOptions{}.stuck_window;      ///< s
  double distance = TrackOptions{}.stuck_distance;  ///< m
};

/// Points of one file, those the rule put at rest, and those the file itself labelled deposited.
struct RestCount {
  std::size_t points = 0, at_rest = 0, labelled_in_file = 0;
};

/// Relabels `tracks` by one rest rule, whatever wrote the file (a tracker labels its rests
/// "deposited", a simulation engine only the particles it attaches or strains): every point
/// of a window of `rule.window` seconds over which the particle is at rest becomes
/// "deposited", every other point labelled "deposited" becomes "mobile". A window (the points
/// of one particle within rule.window of its last one, the track at least that long) is at
/// rest by the tracker's test of a final window (tracking::isStopped): every point within
/// rule.distance of the last one (then all its points rest), or, for noisy positions
/// (6 points or more), the medians of its first and last thirds within r = distance +
/// 3 sigma of each other and 90 % of its points within r of its median, sigma the per-axis
/// noise sqrt(sum |dr|^2 / (4 (n - 1))) of its successive steps (then the points within r of
/// the median rest). analyseTracks leaves out the steps between two resting points and,
/// from Eq. 18, the resting points after the first. Off (window 0): nothing changes.
RestCount labelRests(Tracks& tracks, const RestRule& rule);

struct CompareOptions {
  TrackOptions tracks;
  RestRule rest;
  double occupancy_cell = 5e-6;  ///< m, grid of the streamline occupancy maps
  // Tolerances (the experiment is the reference). Defaults reflect the
  // paper's "agree" judgement on Figs. 15-16 and its 42.3 vs 44.1 % retention.
  double speed_tolerance = 0.20;      ///< relative, mean and median speed
  double dispersion_tolerance = 0.25; ///< relative, time-averaged sigma_x, sigma_y
  double retention_tolerance = 0.05;  ///< absolute, retained fraction
  double iou_minimum = 0.5;           ///< streamline occupancy overlap
  /// Pore bodies and throats of the geometry (both track sets in its frame);
  /// null: no per-region speeds.
  const RegionMap* regions = nullptr;
  /// How the experiment was put in the simulation frame (recorded in metrics.json).
  nlohmann::json alignment;
  /// What the reference tracks are, as the metrics' source names them: "experiment tracks"
  /// for a user's file; compare-tracks names a run of the same validation instead
  /// ("tracks of run NAME"), which may be a tracked rendering of a simulation, not footage.
  std::string reference_name = "experiment tracks";
};

/// Retained fraction against time: particles retained by t (at rest from their
/// stop time on) over particles that entered by t, counted as countRetention does.
struct RetentionSeries {
  std::vector<double> t, fraction;  ///< s, 1
};

struct Comparison {
  TrackStats experiment, simulation;
  double wasserstein = 0, ks_statistic = 0, ks_p_value = 1;  ///< over every per-frame step (steps of one track are correlated)
  /// Kolmogorov-Smirnov over one mean speed per moving track (mobile or deposited):
  /// tracks of different particles are independent samples, so this p-value means
  /// what a p-value says, unlike the per-step one. `track_samples_*`: tracks per side.
  double track_ks_statistic = 0, track_ks_p_value = 1;
  int track_samples_experiment = 0, track_samples_simulation = 0;
  double iou = 0;
  cv::Mat occupancy_experiment, occupancy_simulation;
  RetentionSeries retention_experiment, retention_simulation;
  /// The rest rule and what it found in each file (labelRests): the speeds, their
  /// distributions, the regions' speeds and sigma_x, sigma_y come from the relabelled files.
  RestRule rest_rule;
  RestCount rest_experiment, rest_simulation;
  /// Retention of each file by the one rule of Retention.hpp (retention_fraction compares their fractions).
  RetentionCount retention_count_experiment, retention_count_simulation;
  std::optional<RegionSpeeds> regions_experiment, regions_simulation;
  cv::Mat region_picture;  ///< BGR, when regions were classified
  cv::Mat registration_picture;  ///< BGR frame with the registered grain outlines, when registered
  nlohmann::json regions_info, alignment;
  std::vector<MetricResult> metrics;
  nlohmann::json toJson() const;
};

/// Retention over time on `times` (s) of one file's count.
RetentionSeries retentionOverTime(const RetentionCount& count, const std::vector<double>& times);

/// Metrics of `simulation` against `experiment` (the reference). Throws
/// InputError for degenerate inputs (see TrackChecks.hpp: no rows, single rows,
/// time that does not advance, an experiment without a measurable step).
Comparison compareTracks(const Tracks& experiment, const Tracks& simulation, const CompareOptions& options);

/// Names of the metrics that have a pass/fail verdict and failed.
std::vector<std::string> failedMetrics(const Comparison& c);

/// Writes metrics.json, the time series (mean_speed_time_um_per_s.csv,
/// median_speed_time_um_per_s.csv, sigma_x_time_um.csv, sigma_y_time_um.csv,
/// retention_time.csv), dispersion_frames.csv (the paper's Eq. 18 per frame and
/// side: count, mean and sigma of the moving particles' x and y), speed_histogram.csv, streamlines.png (experiment |
/// simulation | overlay), with regions region_speeds.csv and regions.png, and
/// registration.png when the experiment was registered to the mask.
std::vector<std::string> writeComparison(const Comparison& c, const std::filesystem::path& dir);

}  // namespace mmval::compare
