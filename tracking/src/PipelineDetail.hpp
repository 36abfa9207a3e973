// Pieces of the tracker shared by runTracker (Pipeline.cpp) and the joins of
// deposited particles to the tracks that brought them (PipelineJoins.cpp); their
// numbers are PipelineTuning's (TrackerTuning.hpp).
#pragma once
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <unordered_map>
#include <vector>

#include <opencv2/core.hpp>

#include "TrackerTuning.hpp"
#include "mmval/tracking/Pipeline.hpp"

namespace mmval::tracking::detail {

/// Points bucketed in square cells of `cell` px: everything within `cell` of a position
/// is in its 3 x 3 neighbourhood of cells (keeps the joins below linear in the tracks).
class CellGrid {
 public:
  explicit CellGrid(double cell) : m_cell(cell) {}
  void add(std::size_t item, double x, double y) { m_bins[key(cell(x), cell(y))].push_back(item); }
  template <class F>
  void near(double x, double y, F&& visit) const {
    const long long cx = cell(x), cy = cell(y);
    for (long long i = cx - 1; i <= cx + 1; ++i)
      for (long long j = cy - 1; j <= cy + 1; ++j) {
        const auto it = m_bins.find(key(i, j));
        if (it != m_bins.end())
          for (std::size_t item : it->second) visit(item);
      }
  }

 private:
  long long cell(double v) const { return static_cast<long long>(std::floor(v / m_cell)); }
  static long long key(long long i, long long j) { return i * 1000003LL + j; }
  double m_cell;
  std::unordered_map<long long, std::vector<std::size_t>> m_bins;
};

/// A tracker point at pixel position (x, y) of `frame`, with its time and metres.
inline TrackPoint trackPoint(const TrackConfig& c, std::int64_t frame, std::int64_t particle, double x, double y) {
  TrackPoint t;
  t.frame = frame;
  t.particle = particle;
  t.t = static_cast<double>(frame) / c.fps;
  t.x_px = x;
  t.y_px = y;
  t.x = x * c.pixel_size;
  t.y = y * c.pixel_size;
  return t;
}

/// First and last index of each track in points sorted by particle, then frame.
struct Span {
  std::size_t first, last;
};
inline std::vector<Span> trackSpans(const std::vector<TrackPoint>& pts) {
  std::vector<Span> spans;
  for (std::size_t i = 0; i < pts.size();) {
    std::size_t j = i;
    while (j < pts.size() && pts[j].particle == pts[i].particle) ++j;
    spans.push_back({i, j - 1});
    i = j;
  }
  return spans;
}

/// Back into the tracks order: by particle, then frame.
inline void sortTracks(std::vector<TrackPoint>& pts) {
  std::stable_sort(pts.begin(), pts.end(), [](const TrackPoint& a, const TrackPoint& b) {
    return a.particle != b.particle ? a.particle < b.particle : a.frame < b.frame;
  });
}

/// Joining a track end to a resting place: at most this far from it (px) ...
inline double joinGatePx(const TrackConfig& c) { return std::max(kPipelineTuning.join_gate_min_px, c.link.search_radius); }
/// ... and at most this many frames from the particle's arrival there.
inline int joinGateFrames(const TrackConfig& c) {
  return std::max(kPipelineTuning.join_gate_min_frames, kPipelineTuning.join_gate_memory_factor * (c.link.memory + 1));
}
/// A point this close to a resting place (px) is at it.
inline double restingRadiusPx(const TrackConfig& c) { return std::max(kPipelineTuning.resting_min_px, static_cast<double>(c.detect.refine_radius)); }

/// Least-squares amplitude of a spot (sigma PipelineTuning::spot_sigma_px) at (x, y) in
/// sign x (frame - background) over the window of half-width spot_window_px: ~0 where
/// frame and background agree, about minus a particle's depth where the background holds
/// a particle the frame does not. NaN when the window misses the frame.
inline double spotDifference(const cv::Mat& f, const cv::Mat& background, double x, double y, double sign) {
  constexpr double sigma = kPipelineTuning.spot_sigma_px;
  constexpr int half = kPipelineTuning.spot_window_px;
  const int cx = static_cast<int>(std::lround(x)), cy = static_cast<int>(std::lround(y));
  double sg = 0, sgg = 0;
  for (int yy = std::max(0, cy - half); yy <= std::min(f.rows - 1, cy + half); ++yy)
    for (int xx = std::max(0, cx - half); xx <= std::min(f.cols - 1, cx + half); ++xx) {
      const double g = std::exp(-((xx - x) * (xx - x) + (yy - y) * (yy - y)) / (2 * sigma * sigma));
      sg += g * sign * (f.at<float>(yy, xx) - background.at<float>(yy, xx));
      sgg += g * g;
    }
  return sgg > 0 ? sg / sgg : std::numeric_limits<double>::quiet_NaN();
}

/// Appends `end`'s particle at rest at (x, y) in every frame after `end`, labelled deposited.
inline void restUntilTheEnd(const TrackConfig& c, const TrackPoint& end, double x, double y, const std::vector<int>& frames, std::vector<TrackPoint>& out) {
  for (int f : frames)
    if (f > end.frame) {
      out.push_back(trackPoint(c, f, end.particle, x, y));
      out.back().state = "deposited";
    }
}

/// Deposits the background search did not isolate (a particle against a grain wall, a
/// pair): a moving track that ends in the interior, continued by no other track, where
/// the median background holds a particle that the reference frames before the end lack
/// and those after the end show. The particle arrived there and stayed; its track
/// continues there, at rest, to the end of the video, labelled deposited.
void joinByReference(TrackRun& run, const TrackConfig& c, const std::map<int, cv::Mat>& refs, Polarity polarity, double typical_peak);

/// Particles that deposit onto particles already at rest (clusters, bridges) vanish into
/// their blob: the track ends, in the interior, at a resting place after the particle
/// there stopped, and no track begins nearby in the frames after (which a particle
/// passing over the blob would start). Such a track continues at the resting place, at
/// rest, to the end of the video, labelled deposited.
void joinClusterArrivals(TrackRun& run, const TrackConfig& c);

}  // namespace mmval::tracking::detail
