// Retention counted by one rule on any tracks file: a tracker's tracks.csv (of
// a real experiment or of a rendered simulation) and simulated trajectories
// alike, so that the two fractions compare the same quantity.
//
//   retained fraction = particles that came to rest / particles that entered
//
// - Particles, not tracks: a tracker loses a particle (a passer hides it, it
//   leaves focus) and picks it up under a new id. Tracks are chained: a track
//   that did not enter continues the chain whose last track ended closest to
//   where it began, at most link_gap before, no farther than the file's fast
//   particles travel in that time. A chain is one particle: it enters once
//   and is retained at most once, so the fraction is at most 1.
// - Entered: a chain's first track begins in the first frames or within
//   entry_margin of the edge of the view. Chains that begin inside the view
//   mid-record and continue nothing are orphans: reported, never counted.
// - At rest (restAtEnd): the chain's rows (its tracks in time order, so that
//   a last track shorter than the window is judged with the rows before it)
//   end with a final stuck_window whose drift speed (median position of the
//   window's first third to that of its last third, over their time
//   separation) is below
//   rest speed = stuck_distance / stuck_window plus three standard errors of
//   that drift for the track's localisation noise (zero for exact positions).
//   A particle that crawls slower than the rest speed is at rest on both
//   sides; one that crawls faster is not, whatever a file's labels say. Only
//   positions and times decide; the noise term only widens the threshold by
//   what noise can fake (for 0.7 um noise at 40 fps over 2 s: ~0.55 um/s).
// - A track that ends before the record does, on a row labelled "deposited",
//   is taken to stay at its resting place (the median of its final
//   deposited rows) until the record ends: a simulator stops writing a
//   particle once it attaches, and a tracker loses a resting particle behind
//   a passer. The label says where the particle stays, not whether it stopped:
//   the drift rule still decides (a deposit in the last stuck_window is not
//   yet a rest, on either side).
#pragma once
#include <optional>
#include <vector>

#include <opencv2/core.hpp>

#include "mmval/core/Tracks.hpp"
#include "mmval/tracking/TrackMetrics.hpp"

namespace mmval::compare {

struct RetentionOptions {
  /// immobile_distance, min_points: which tracks move (as tracking::analyseTracks);
  /// stuck_window, stuck_distance: the rest rule; entry_margin: the entry rule.
  tracking::TrackOptions tracks;
  /// m: the field of view, for the entry rule (the geometry window when known);
  /// none: the 0.1 % .. 99.9 % quantile box of the file's positions, which a
  /// few rows outside the frame (a centroid cut by the edge) do not stretch.
  std::optional<cv::Rect2d> view;
  double link_gap = 1.0;           ///< s: longest time between a track's end and its continuation's start
  double link_slack = 20e-6;       ///< m: added to the distance a lost particle can travel in the gap
  double link_speed_quantile = 0.99;  ///< the file's step speed that bounds that travel (this quantile of all steps)
};

/// Whether one track (or one chain of tracks) ends at rest, and the numbers behind the verdict.
struct RestVerdict {
  bool at_rest = false;
  double drift_speed = 0;   ///< m/s over the final window (NaN: no full window)
  double threshold = 0;     ///< m/s: rest speed + 3 standard errors
  double noise = 0;         ///< m, per-axis localisation noise estimated from the track's steps
  double stop_time = 0;     ///< s: start of the final stretch at the resting place (at_rest only)
  bool held = false;        ///< the track ended early on a "deposited" row and was held to t_end
};

/// The rest rule (see the file comment) on `points`, the rows of one track or chain sorted by
/// frame, in a record that ends at `t_end` (s) with frames `frame_dt` (s) apart.
RestVerdict restAtEnd(const std::vector<TrackPoint>& points, double t_end, double frame_dt, const tracking::TrackOptions& options);

struct RetentionCount {
  int entered = 0;    ///< chains whose first track entered
  int retained = 0;   ///< entered chains that end at rest
  double fraction = 0;  ///< retained / entered (NaN when nothing entered), at most 1
  int tracks = 0;     ///< tracks in chains: moving ones, and resting ones that continue a chain
  int continued = 0;  ///< tracks linked as the continuation of an earlier one
  int orphans = 0;    ///< moving chains that neither entered nor continue one: not counted
  int orphans_at_rest = 0;
  /// entered chains whose last track ends on a row the file labels "deposited": for
  /// simulated trajectories, the engine's deposits; for tracks, the tracker's own rule.
  int labelled_deposited = 0;
  double rest_speed = 0;   ///< m/s, stuck_distance / stuck_window
  double link_speed = 0;   ///< m/s used to link tracks
  std::vector<double> entry_times;  ///< s, first time of each entered chain
  std::vector<double> stop_times;   ///< s, stop time of each retained chain
};

/// Counts retention in `tracks` (sorted by particle, then frame) by the rule of this file.
RetentionCount countRetention(const Tracks& tracks, const RetentionOptions& options);

}  // namespace mmval::compare
