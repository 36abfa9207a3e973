// Experiment vs simulation, metric by metric, on the shared tracks schema.
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mmval/tracking/TrackMetrics.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/Tracks.hpp"

namespace mmval::compare {

using tracking::TrackOptions;
using tracking::TrackStats;
using tracking::TimeSeries;

struct CompareOptions {
  TrackOptions tracks;
  double occupancy_cell = 5e-6;  ///< m, grid of the streamline occupancy maps
  // Tolerances (the experiment is the reference). Defaults reflect the
  // paper's "agree" judgement on Figs. 15-16 and its 42.3 vs 44.1 % retention.
  double speed_tolerance = 0.20;      ///< relative, mean and median speed
  double dispersion_tolerance = 0.25; ///< relative, time-averaged sigma_x, sigma_y
  double retention_tolerance = 0.05;  ///< absolute, retained fraction
  double iou_minimum = 0.5;           ///< streamline occupancy overlap
};

struct Comparison {
  TrackStats experiment, simulation;
  double wasserstein = 0, ks_statistic = 0, ks_p_value = 1;
  double iou = 0;
  cv::Mat occupancy_experiment, occupancy_simulation;
  std::vector<MetricResult> metrics;
  nlohmann::json toJson() const;
};

Comparison compareTracks(const Tracks& experiment, const Tracks& simulation, const CompareOptions& options);

/// Writes metrics.json, velocity_time.csv, dispersion_time.csv, speed_histogram.csv
/// and streamlines.png (experiment | simulation | overlay) into `dir`.
std::vector<std::string> writeComparison(const Comparison& c, const std::filesystem::path& dir);

}  // namespace mmval::compare
