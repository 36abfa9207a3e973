// Statistics of one set of tracks (experiment or simulation), as the paper
// measures them: velocities of mobile particles (immobile ones left out),
// dispersion sigma_x(t), sigma_y(t) (population std of positions, Eq. 18),
// retention (particles that moved and then stopped), and the streamline
// occupancy map (every position of every frame composited).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "mmval/core/Tracks.hpp"

namespace mmval::tracking {

struct TrackOptions {
  double immobile_distance = 2e-6;  ///< m: a particle that never gets farther than this from its start is immobile
  double stuck_window = 2.0;        ///< s: a mobile particle that moved less than stuck_distance over its last window is retained
  double stuck_distance = 1e-6;     ///< m
  int time_bins = 20;               ///< bins for velocity and dispersion against time
  int min_points = 3;               ///< shorter tracks are "short" (likely noise): in no statistic
};

struct Step {
  std::int64_t particle = 0;
  double t = 0;          ///< mid-step time, s
  double x = 0, y = 0;   ///< mid-step position, m
  double vx = 0, vy = 0; ///< m/s
  double speed = 0;      ///< m/s
};

struct TimeSeries {
  std::vector<double> t;          ///< bin centres, s
  std::vector<double> mean_speed, median_speed;  ///< m/s, NaN in empty bins
  std::vector<double> sigma_x, sigma_y;           ///< m
  std::vector<int> count;
};

struct TrackSummary {
  std::int64_t particle = 0;
  int points = 0;
  double duration = 0;          ///< s
  double mean_speed = 0;        ///< m/s
  double path_length = 0;       ///< m
  double net_displacement = 0;  ///< m, first to last
  double straightness = 0;      ///< net / path (1: straight line)
  std::string state;            ///< mobile, immobile, deposited, short
};

struct FrameDispersion {
  std::int64_t frame = 0;
  double t = 0;
  int count = 0;
  double mean_x = 0, mean_y = 0, sigma_x = 0, sigma_y = 0;  ///< m
};

/// Ensemble mean-square displacement of mobile particles against lag, and its
/// power-law fit MSD = 4 D t^alpha (2D), plus D from a line through the origin.
struct Msd {
  std::vector<double> lag, msd;  ///< s, m^2
  std::vector<long long> samples;
  double alpha = 0, d_power = 0, d_linear = 0;  ///< exponent; D (m^2/s) of the two fits
};

struct TrackStats {
  std::vector<Step> steps;  ///< of mobile particles
  TimeSeries series;
  int particles = 0, immobile = 0, mobile = 0, retained = 0, short_tracks = 0;
  double retained_fraction = 0;          ///< retained / mobile
  double mean_speed = 0, median_speed = 0;  ///< m/s over all steps
  double sigma_x = 0, sigma_y = 0;          ///< m, time-averaged dispersion (0 when no frame has two mobile particles)
  double t_begin = 0, t_end = 0;
  std::vector<TrackSummary> tracks;
  std::vector<FrameDispersion> frames;
  Msd msd;
};

TrackStats analyseTracks(const Tracks& tracks, const TrackOptions& options);

/// The ensemble MSD of the mobile tracks of `stats` (called by analyseTracks).
Msd ensembleMsd(const Tracks& tracks, const TrackStats& stats, const TrackOptions& options);

/// Occupancy of positions on a grid of `cell` metres over [x0, x1] x [y0, y1].
cv::Mat occupancyMap(const Tracks& tracks, double cell, double x0, double y0, double x1, double y1);

/// Intersection over union of two binary maps of the same size.
double intersectionOverUnion(const cv::Mat& a, const cv::Mat& b);

}  // namespace mmval::tracking
