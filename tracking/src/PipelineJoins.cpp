#include "PipelineDetail.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <vector>

namespace mmval::tracking::detail {

void joinByReference(TrackRun& run, const TrackConfig& c, const std::map<int, cv::Mat>& refs, Polarity polarity, double typical_peak) {
  auto& pts = run.tracks.points;
  if (pts.empty() || run.frame_index.empty()) return;
  const int last_frame = *std::max_element(run.frame_index.begin(), run.frame_index.end());
  const double gate_px = joinGatePx(c);
  const int gate_frames = joinGateFrames(c);
  const double sign = polarity == Polarity::bright ? 1.0 : -1.0;
  const double margin = restingRadiusPx(c);
  const std::vector<Span> spans = trackSpans(pts);
  CellGrid starts(gate_px);
  for (std::size_t k = 0; k < spans.size(); ++k) starts.add(k, pts[spans[k].first].x_px, pts[spans[k].first].y_px);
  std::vector<int> frames = run.frame_index;
  std::sort(frames.begin(), frames.end());
  std::vector<TrackPoint> added;
  for (const Span& s : spans) {
    const TrackPoint& e = pts[s.last];
    if (e.state == "deposited" || e.frame + gate_frames > last_frame || s.last - s.first + 1 < static_cast<std::size_t>(c.analysis.min_points)) continue;
    if (e.x_px < margin || e.y_px < margin || e.x_px > run.background.cols - 1 - margin || e.y_px > run.background.rows - 1 - margin) continue;
    double reach = 0;
    for (std::size_t k = s.first; k <= s.last; ++k) reach = std::max(reach, std::hypot(pts[k].x - pts[s.first].x, pts[k].y - pts[s.first].y));
    if (reach < c.analysis.immobile_distance) continue;
    bool continued = false;
    starts.near(e.x_px, e.y_px, [&](std::size_t k) {
      const TrackPoint& b = pts[spans[k].first];
      continued = continued || (b.frame > e.frame && b.frame <= e.frame + gate_frames && std::hypot(b.x_px - e.x_px, b.y_px - e.y_px) <= gate_px);
    });
    if (continued) continue;
    // Where it rests: its last position, or one more step along its last velocity.
    std::vector<cv::Point2d> places = {{e.x_px, e.y_px}};
    if (s.last > s.first) places.emplace_back(2 * e.x_px - pts[s.last - 1].x_px, 2 * e.y_px - pts[s.last - 1].y_px);
    for (const cv::Point2d& q : places) {
      int before = 0, missing_before = 0, after = 0, missing_after = 0;
      for (const auto& [f, img] : refs) {
        if (f < e.frame - 1) {
          ++before;
          missing_before += spotDifference(img, run.background, q.x, q.y, sign) < -kPipelineTuning.missing_fraction * typical_peak ? 1 : 0;
        } else if (f > e.frame + 1) {
          ++after;
          missing_after += spotDifference(img, run.background, q.x, q.y, sign) < -kPipelineTuning.missing_fraction * typical_peak ? 1 : 0;
        }
      }
      if (before == 0 || after == 0 || missing_before * 4 < before * kPipelineTuning.missing_before_quarters ||
          missing_after * 4 > after * kPipelineTuning.missing_after_quarters) continue;
      restUntilTheEnd(c, e, q.x, q.y, frames, added);
      ++run.deposits_by_reference;
      break;
    }
  }
  pts.insert(pts.end(), added.begin(), added.end());
  sortTracks(pts);
}

void joinClusterArrivals(TrackRun& run, const TrackConfig& c) {
  auto& pts = run.tracks.points;
  if (pts.empty() || run.frame_index.empty()) return;
  const int last_frame = *std::max_element(run.frame_index.begin(), run.frame_index.end());
  const double near = restingRadiusPx(c);
  const double gate_px = joinGatePx(c);
  const int gate_frames = joinGateFrames(c);
  const std::vector<Span> spans = trackSpans(pts);
  struct Site {
    double x, y;
    std::int64_t since;
  };
  std::vector<Site> sites;  // resting places: deposited tracks from their stop, immobile ones throughout
  for (const Span& s : spans) {
    const TrackPoint& l = pts[s.last];
    if (l.state == "deposited") {
      std::size_t k = s.last;
      while (k > s.first && pts[k - 1].state == "deposited") --k;
      sites.push_back({l.x_px, l.y_px, pts[k].frame});
    } else if (s.last - s.first + 1 >= static_cast<std::size_t>(c.analysis.min_points) && l.frame == last_frame) {
      double reach = 0;
      for (std::size_t k = s.first; k <= s.last; ++k) reach = std::max(reach, std::hypot(pts[k].x - pts[s.first].x, pts[k].y - pts[s.first].y));
      if (reach < c.analysis.immobile_distance) sites.push_back({l.x_px, l.y_px, pts[s.first].frame});
    }
  }
  if (sites.empty()) return;
  CellGrid site_grid(near);
  for (std::size_t k = 0; k < sites.size(); ++k) site_grid.add(k, sites[k].x, sites[k].y);
  std::vector<std::size_t> by_start(spans.size());
  for (std::size_t k = 0; k < spans.size(); ++k) by_start[k] = k;
  std::sort(by_start.begin(), by_start.end(), [&](std::size_t a, std::size_t b) { return pts[spans[a].first].frame < pts[spans[b].first].frame; });
  std::vector<TrackPoint> added;
  std::vector<int> frames = run.frame_index;
  std::sort(frames.begin(), frames.end());
  for (const Span& s : spans) {
    const TrackPoint& e = pts[s.last];
    if (e.state == "deposited" || e.frame + gate_frames > last_frame || s.last - s.first + 1 < static_cast<std::size_t>(c.analysis.min_points)) continue;
    double reach = 0;  // a moving track: a stationary one here is the resting particle itself
    for (std::size_t k = s.first; k <= s.last; ++k) reach = std::max(reach, std::hypot(pts[k].x - pts[s.first].x, pts[k].y - pts[s.first].y));
    if (reach < c.analysis.immobile_distance) continue;
    const Site* site = nullptr;
    site_grid.near(e.x_px, e.y_px, [&](std::size_t k) {
      const Site& st = sites[k];
      const double d = std::hypot(e.x_px - st.x, e.y_px - st.y);
      if (e.frame + 1 >= st.since && d <= near && (site == nullptr || d < std::hypot(e.x_px - site->x, e.y_px - site->y))) site = &st;
    });
    if (site == nullptr) continue;
    bool continued = false;
    auto from = std::lower_bound(by_start.begin(), by_start.end(), e.frame + 1,
                                 [&](std::size_t k, std::int64_t f) { return pts[spans[k].first].frame < f; });
    for (auto it = from; it != by_start.end() && pts[spans[*it].first].frame <= e.frame + gate_frames; ++it) {
      const Span& o = spans[*it];
      const TrackPoint& b = pts[o.first];
      if (std::hypot(b.x_px - e.x_px, b.y_px - e.y_px) > gate_px) continue;
      // A track that begins there and leaves the resting place is the particle moving on;
      // one that stays is the cluster itself.
      for (std::size_t k = o.first; k <= o.last && !continued; ++k) continued = std::hypot(pts[k].x_px - site->x, pts[k].y_px - site->y) > near;
      if (continued) break;
    }
    if (continued) continue;
    restUntilTheEnd(c, e, site->x, site->y, frames, added);
    ++run.cluster_arrivals;
  }
  pts.insert(pts.end(), added.begin(), added.end());
  sortTracks(pts);
}

}  // namespace mmval::tracking::detail
