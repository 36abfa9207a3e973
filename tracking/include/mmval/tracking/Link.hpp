// Linking detections into tracks, frame by frame (streaming).
//
// Two linkers:
//  - paper: the source paper's rule. Candidates inside a search radius around
//    the predicted position; the one with the smallest combination of linear
//    and angular displacement relative to the particle's previous motion wins
//    (cost = d / R + w * angle / pi); conflicts go to the cheaper link.
//  - global: one optimal assignment per frame (Hungarian method on each
//    connected component of the sparse candidate graph, with a "no link"
//    alternative for every track), motion prediction from the track's
//    velocity (a track too new to have one borrows the mean velocity of the
//    tracks around it: in a pore flow, neighbours follow nearby streamlines),
//    and gap closing over up to `memory` missed frames.
// Both find candidates through a uniform grid, so dense frames (thousands of
// particles) cost O(N) candidate searches, not O(N^2).
#pragma once
#include <cstdint>
#include <vector>

#include "mmval/tracking/Detect.hpp"

namespace mmval::tracking {

enum class Linker { paper, global };

/// Where a track is looked for in the next frame. none: where it was (Brownian steps
/// are uncorrelated: the last one predicts nothing, and extrapolating it doubles the
/// distance to the right candidate); velocity: one smoothed step further along the
/// track's own velocity; neighbours: as velocity, and a track too new to have one borrows
/// the mean velocity of the tracks within neighbour_radius (particles in a pore flow
/// follow nearby streamlines); automatic: velocity, with neighbours when
/// neighbour_radius > 0 (the tracker sets none for Brownian motion, Pipeline.hpp).
enum class Prediction { automatic, none, velocity, neighbours };

struct LinkOptions {
  Linker method = Linker::global;
  double search_radius = 8.0;  ///< px per frame
  int memory = 2;              ///< frames a track may be missed and still continue
  Prediction predict = Prediction::automatic;
  double angle_weight = 0.5;   ///< paper: weight of the turning angle against the distance
  /// weight of the previous velocity in the prediction's exponential filter (0: last step only)
  double velocity_smoothing = 0.7;
  int max_component = 400;     ///< larger candidate components fall back to greedy (logged in stats)
  /// px: a track without a velocity of its own predicts with the mean velocity of the tracks
  /// that have one within this distance (0: no prediction until its second point); used by
  /// Prediction::neighbours and automatic
  double neighbour_radius = 0.0;
};

struct LinkedPoint {
  int frame = 0;
  std::int64_t particle = 0;
  double x = 0, y = 0;
  Detection detection;
};

struct LinkStats {
  long long links = 0, new_tracks = 0, gap_closures = 0, greedy_components = 0, largest_component = 0;
  long long neighbour_predictions = 0;  ///< candidate searches of new tracks led by their neighbours' velocity
};

class TrackLinker {
 public:
  explicit TrackLinker(LinkOptions options) : m_o(options) {}
  /// Adds one frame's detections; frames must come in increasing order.
  void push(int frame, const std::vector<Detection>& detections);
  /// All linked points so far, sorted by particle then frame.
  std::vector<LinkedPoint> points() const;
  const LinkStats& stats() const { return m_stats; }

 private:
  struct Track {
    std::int64_t id;
    int last_frame;
    double x, y, vx = 0, vy = 0;
    bool has_velocity = false;
  };
  LinkOptions m_o;
  std::vector<Track> m_active;
  std::vector<LinkedPoint> m_points;
  std::int64_t m_next_id = 0;
  LinkStats m_stats;
};

}  // namespace mmval::tracking
