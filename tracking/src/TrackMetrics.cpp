#include "mmval/tracking/TrackMetrics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <string>

#include "mmval/tracking/Statistics.hpp"

namespace mmval::tracking {

TrackStats analyseTracks(const Tracks& tracks, const TrackOptions& o) {
  TrackStats s;
  const auto& pts = tracks.points;
  if (pts.empty()) return s;
  s.t_begin = std::numeric_limits<double>::max();
  s.t_end = std::numeric_limits<double>::lowest();
  for (const auto& p : pts) {
    s.t_begin = std::min(s.t_begin, p.t);
    s.t_end = std::max(s.t_end, p.t);
  }
  std::vector<const TrackPoint*> mobile_points;
  for (std::size_t i = 0; i < pts.size();) {
    std::size_t j = i;
    while (j < pts.size() && pts[j].particle == pts[i].particle) ++j;
    ++s.particles;
    double reach = 0;
    for (std::size_t k = i; k < j; ++k) reach = std::max(reach, std::hypot(pts[k].x - pts[i].x, pts[k].y - pts[i].y));
    TrackSummary ts;
    ts.particle = pts[i].particle;
    ts.points = static_cast<int>(j - i);
    ts.duration = pts[j - 1].t - pts[i].t;
    for (std::size_t k = i + 1; k < j; ++k) ts.path_length += std::hypot(pts[k].x - pts[k - 1].x, pts[k].y - pts[k - 1].y);
    ts.net_displacement = std::hypot(pts[j - 1].x - pts[i].x, pts[j - 1].y - pts[i].y);
    ts.straightness = ts.path_length > 0 ? ts.net_displacement / ts.path_length : 0;
    ts.mean_speed = ts.duration > 0 ? ts.path_length / ts.duration : 0;
    const int retained_before = s.retained;
    if (static_cast<int>(j - i) < o.min_points) {
      ++s.short_tracks;
      ts.state = "short";
    } else if (reach < o.immobile_distance) {
      ++s.immobile;
      ts.state = "immobile";
    } else {
      ++s.mobile;
      for (std::size_t k = i; k < j; ++k) mobile_points.push_back(&pts[k]);
      for (std::size_t k = i + 1; k < j; ++k) {
        const double dt = pts[k].t - pts[k - 1].t;
        if (dt <= 0) continue;
        Step st;
        st.particle = pts[k].particle;
        st.t = 0.5 * (pts[k].t + pts[k - 1].t);
        st.x = 0.5 * (pts[k].x + pts[k - 1].x);
        st.y = 0.5 * (pts[k].y + pts[k - 1].y);
        st.vx = (pts[k].x - pts[k - 1].x) / dt;
        st.vy = (pts[k].y - pts[k - 1].y) / dt;
        st.speed = std::hypot(st.vx, st.vy);
        s.steps.push_back(st);
      }
      // Retained: the final window shows (almost) no motion, or the file says so
      // (simulated trajectories mark a particle "deposited" where it attaches).
      const double t_last = pts[j - 1].t;
      if (pts[j - 1].state == "deposited") {
        ++s.retained;
      } else if (t_last - pts[i].t >= o.stuck_window) {
        double moved = 0;
        for (std::size_t k = i; k < j; ++k)
          if (pts[k].t >= t_last - o.stuck_window) moved = std::max(moved, std::hypot(pts[k].x - pts[j - 1].x, pts[k].y - pts[j - 1].y));
        if (moved < o.stuck_distance) ++s.retained;
      }
      ts.state = s.retained > retained_before ? "deposited" : "mobile";
    }
    s.tracks.push_back(ts);
    i = j;
  }
  s.retained_fraction = s.mobile > 0 ? static_cast<double>(s.retained) / s.mobile : 0.0;
  std::vector<double> speeds;
  for (const auto& st : s.steps) speeds.push_back(st.speed);
  s.mean_speed = mean(speeds);
  s.median_speed = median(speeds);

  // Time series.
  const int nb = std::max(1, o.time_bins);
  const double span = std::max(s.t_end - s.t_begin, 1e-300);
  auto bin = [&](double t) { return std::clamp(static_cast<int>((t - s.t_begin) / span * nb), 0, nb - 1); };
  std::vector<std::vector<double>> bin_speed(nb), bin_x(nb), bin_y(nb);
  for (const auto& st : s.steps) bin_speed[bin(st.t)].push_back(st.speed);
  // Dispersion per frame (the paper's Eq. 18), then averaged within the bin.
  std::map<std::int64_t, std::pair<std::vector<double>, std::vector<double>>> frames;
  std::map<std::int64_t, double> frame_time;
  for (const auto* p : mobile_points) {
    frames[p->frame].first.push_back(p->x);
    frames[p->frame].second.push_back(p->y);
    frame_time[p->frame] = p->t;
  }
  std::vector<double> all_sx, all_sy;
  for (const auto& [f, xy] : frames) {
    FrameDispersion fd;
    fd.frame = f;
    fd.t = frame_time[f];
    fd.count = static_cast<int>(xy.first.size());
    fd.mean_x = mean(xy.first);
    fd.mean_y = mean(xy.second);
    fd.sigma_x = populationStd(xy.first);
    fd.sigma_y = populationStd(xy.second);
    s.frames.push_back(fd);
    if (xy.first.size() < 2) continue;
    const double sx = fd.sigma_x, sy = fd.sigma_y;
    bin_x[bin(frame_time[f])].push_back(sx);
    bin_y[bin(frame_time[f])].push_back(sy);
    all_sx.push_back(sx);
    all_sy.push_back(sy);
  }
  // No frame with two or more mobile particles (nothing moves, or one particle at a
  // time): no spread to measure; 0, not the NaN of an empty mean, which JSON cannot hold.
  s.sigma_x = all_sx.empty() ? 0.0 : mean(all_sx);
  s.sigma_y = all_sy.empty() ? 0.0 : mean(all_sy);
  for (int b = 0; b < nb; ++b) {
    s.series.t.push_back(s.t_begin + (b + 0.5) * span / nb);
    s.series.mean_speed.push_back(mean(bin_speed[b]));
    s.series.median_speed.push_back(median(bin_speed[b]));
    s.series.sigma_x.push_back(mean(bin_x[b]));
    s.series.sigma_y.push_back(mean(bin_y[b]));
    s.series.count.push_back(static_cast<int>(bin_speed[b].size()));
  }
  s.msd = ensembleMsd(tracks, s, o);
  return s;
}

Msd ensembleMsd(const Tracks& tracks, const TrackStats& stats, const TrackOptions& o) {
  Msd out;
  std::map<std::int64_t, const TrackSummary*> state;
  for (const auto& t : stats.tracks) state[t.particle] = &t;
  // Lags in frames up to a quarter of the longest track (the usual reliability limit).
  std::map<std::int64_t, std::vector<const TrackPoint*>> by_particle;
  for (const auto& p : tracks.points)
    if (state.count(p.particle) && state[p.particle]->state != "immobile") by_particle[p.particle].push_back(&p);
  std::size_t longest = 0;
  for (const auto& [id, v] : by_particle) longest = std::max(longest, v.size());
  const int max_lag = std::max(1, static_cast<int>(longest / 4));
  std::vector<double> sum(max_lag + 1, 0), dt(max_lag + 1, 0);
  std::vector<long long> n(max_lag + 1, 0);
  for (const auto& [id, v] : by_particle) {
    std::map<std::int64_t, const TrackPoint*> at;
    for (const auto* p : v) at[p->frame] = p;
    for (const auto& [f, p] : at)
      for (int lag = 1; lag <= max_lag; ++lag) {
        auto it = at.find(f + lag);
        if (it == at.end()) continue;
        const double dx = it->second->x - p->x, dy = it->second->y - p->y;
        sum[lag] += dx * dx + dy * dy;
        dt[lag] += it->second->t - p->t;
        ++n[lag];
      }
  }
  double sxy = 0, sxx = 0, lx = 0, ly = 0, lxx = 0, lxy = 0;
  int m = 0;
  for (int lag = 1; lag <= max_lag; ++lag) {
    if (n[lag] == 0) continue;
    const double t = dt[lag] / n[lag], msd = sum[lag] / n[lag];
    out.lag.push_back(t);
    out.msd.push_back(msd);
    out.samples.push_back(n[lag]);
    sxy += t * msd;
    sxx += t * t;
    if (msd > 0 && t > 0) {
      lx += std::log(t);
      ly += std::log(msd);
      lxx += std::log(t) * std::log(t);
      lxy += std::log(t) * std::log(msd);
      ++m;
    }
  }
  (void)o;
  if (sxx > 0) out.d_linear = sxy / sxx / 4.0;
  if (m >= 2) {
    out.alpha = (m * lxy - lx * ly) / (m * lxx - lx * lx);
    out.d_power = std::exp((ly - out.alpha * lx) / m) / 4.0;
  }
  return out;
}

cv::Mat occupancyMap(const Tracks& tracks, double cell, double x0, double y0, double x1, double y1) {
  const int w = std::max(1, static_cast<int>(std::ceil((x1 - x0) / cell)));
  const int h = std::max(1, static_cast<int>(std::ceil((y1 - y0) / cell)));
  cv::Mat m = cv::Mat::zeros(h, w, CV_8U);
  for (const auto& p : tracks.points) {
    const int i = static_cast<int>((p.x - x0) / cell), j = static_cast<int>((p.y - y0) / cell);
    if (i >= 0 && i < w && j >= 0 && j < h) m.at<unsigned char>(j, i) = 255;
  }
  return m;
}

double intersectionOverUnion(const cv::Mat& a, const cv::Mat& b) {
  CV_Assert(a.size() == b.size() && a.type() == CV_8U && b.type() == CV_8U);
  cv::Mat inter, uni;
  cv::bitwise_and(a, b, inter);
  cv::bitwise_or(a, b, uni);
  const int u = cv::countNonZero(uni);
  return u == 0 ? 0.0 : static_cast<double>(cv::countNonZero(inter)) / u;
}

}  // namespace mmval::tracking
