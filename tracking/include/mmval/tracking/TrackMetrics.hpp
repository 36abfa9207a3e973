// Statistics of one set of tracks (experiment or simulation), as the paper
// measures them: velocities of mobile particles (immobile ones left out),
// dispersion sigma_x(t), sigma_y(t) (population std of positions, Eq. 18),
// retention (particles that moved and then stopped), and the streamline
// occupancy map (every position of every frame composited).
#pragma once
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "mmval/core/Tracks.hpp"
#include "mmval/tracking/Brownian.hpp"

namespace mmval::tracking {

struct TrackOptions {
  double immobile_distance = 2e-6;  ///< m: a particle that never gets farther than this from its start is immobile
  double stuck_window = 2.0;        ///< s: a mobile particle that moved less than stuck_distance over its last window is retained
  double stuck_distance = 1e-6;     ///< m
  int time_bins = 20;               ///< bins for velocity and dispersion against time
  int min_points = 3;               ///< shorter tracks are "short" (likely noise): in no statistic
  /// fraction of the view's smaller side: a mobile track that begins this close to the edge
  /// of the field of view (or in the first frames) is a particle entering; one that begins
  /// deeper inside, later, is the continuation of a track the tracker lost
  double entry_margin = 0.05;
  /// flow: the statistics below (velocities, dispersion, retention, deposits); brownian:
  /// Brownian.hpp (drift, D, exponent, localisation error); automatic: decideMotion on
  /// the tracks (the tracker decides, Pipeline.hpp). analyseTracks is the flow analysis.
  MotionModel motion = MotionModel::automatic;
  BrownianOptions brownian;
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
  double stop_time = std::numeric_limits<double>::quiet_NaN();  ///< s, deposited: when it stopped for good
  bool entered = false;         ///< mobile and deposited: began in the first frames or at the view's edge
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
  int entered = 0;  ///< mobile tracks that begin in the first frames or within entry_margin of the view's edge
  double retained_fraction = 0;          ///< retained / entered (retained / mobile when none entered), at most 1
  double mean_speed = 0, median_speed = 0;  ///< m/s over all steps
  double sigma_x = 0, sigma_y = 0;          ///< m, time-averaged dispersion (0 when no frame has two mobile particles)
  double t_begin = 0, t_end = 0;
  std::vector<TrackSummary> tracks;
  std::vector<FrameDispersion> frames;
  Msd msd;
};

/// Per-track statistics. A mobile track is retained ("deposited") when its last point
/// has state "deposited" (simulated trajectories, or a tracker that saw the particle
/// stop) or when its final stuck_window shows no motion beyond stuck_distance plus what
/// localisation noise explains (see isStopped). Points labelled "deposited" that follow
/// another deposited point are the particle sitting where it attached: they count for
/// retention but not in velocities, dispersion or MSD (simulations stop writing a
/// particle once it deposits; a tracked one would otherwise add zero-speed steps).
TrackStats analyseTracks(const Tracks& tracks, const TrackOptions& options);

/// Whether points [first, last) of one track (sorted by frame) end at rest over the final
/// stuck_window: every point of it within stuck_distance of the last point (exact
/// positions), or, for noisy positions, the window's first and last thirds with medians
/// within stuck_distance + 3 sigma and 90 % of its points within that of its median,
/// sigma being the per-axis localisation noise estimated from successive differences in
/// the window (a particle at rest has E|dr|^2 = 4 sigma^2). Needs 6 points for the latter.
bool isStopped(const std::vector<TrackPoint>& points, std::size_t first, std::size_t last, const TrackOptions& options);

/// isStopped's test on a given window, points [begin, end) of one track: at rest when every point
/// is within `distance` of the last (`exact`), or, with 6 points or more, by the noisy-position
/// test (radius = distance + 3 sigma about the window's per-axis median `centre_x`, `centre_y`).
/// Used by isStopped and by compare-tracks' one rest rule on both sides.
struct RestWindow {
  bool at_rest = false;
  bool exact = false;  ///< every point within `distance` of the last
  double centre_x = 0, centre_y = 0, radius = 0;  ///< noisy test: its median and radius
};
RestWindow restWindow(const std::vector<TrackPoint>& points, std::size_t begin, std::size_t end, double distance);

/// Index of the first point of the final stretch at rest of points [first, last): back
/// from the end while points stay within stuck_distance + 3 sigma (as isStopped) of the
/// final window's median position; one stray point does not end the stretch, two do.
std::size_t stopIndex(const std::vector<TrackPoint>& points, std::size_t first, std::size_t last, const TrackOptions& options);

/// Labels, in place, the resting end (from stopIndex on) of every track that is neither
/// short nor immobile and that isStopped or already ends in a "deposited" point, with
/// state "deposited"; other points keep their state. `tracks` sorted by particle, frame.
void markDeposits(Tracks& tracks, const TrackOptions& options);

/// The ensemble MSD of the mobile tracks of `stats` (called by analyseTracks).
Msd ensembleMsd(const Tracks& tracks, const TrackStats& stats, const TrackOptions& options);

/// Occupancy of positions on a grid of `cell` metres over [x0, x1] x [y0, y1].
cv::Mat occupancyMap(const Tracks& tracks, double cell, double x0, double y0, double x1, double y1);

/// Intersection over union of two binary maps of the same size.
double intersectionOverUnion(const cv::Mat& a, const cv::Mat& b);

}  // namespace mmval::tracking
