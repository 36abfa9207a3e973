#include "mmval/tracking/TrackMetrics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <string>

#include "mmval/tracking/Statistics.hpp"

namespace mmval::tracking {

namespace {

/// First point of the final window of [i, j): those within stuck_window of the last.
std::size_t windowBegin(const std::vector<TrackPoint>& pts, std::size_t i, std::size_t j, const TrackOptions& o) {
  std::size_t k = j - 1;
  while (k > i && pts[k - 1].t >= pts[j - 1].t - o.stuck_window - 1e-12) --k;
  return k;
}

/// Per-axis localisation noise of points [b, j) if they are at rest: successive
/// differences of a resting particle have E|dr|^2 = 4 sigma^2 (2D, independent errors).
double restingNoise(const std::vector<TrackPoint>& pts, std::size_t b, std::size_t j) {
  if (j - b < 2) return 0.0;
  double sum = 0;
  for (std::size_t k = b + 1; k < j; ++k) sum += std::pow(pts[k].x - pts[k - 1].x, 2) + std::pow(pts[k].y - pts[k - 1].y, 2);
  return std::sqrt(sum / (4.0 * static_cast<double>(j - b - 1)));
}

/// Per-axis medians of points [b, e).
void medianOf(const std::vector<TrackPoint>& pts, std::size_t b, std::size_t e, double& mx, double& my) {
  std::vector<double> xs, ys;
  for (std::size_t k = b; k < e; ++k) {
    xs.push_back(pts[k].x);
    ys.push_back(pts[k].y);
  }
  mx = median(xs);
  my = median(ys);
}

/// A point where the particle sits attached: labelled deposited, after a deposited point.
bool restingTail(const std::vector<TrackPoint>& pts, std::size_t i, std::size_t k) {
  return k > i && pts[k].state == "deposited" && pts[k - 1].state == "deposited";
}

/// Start of the trailing run of points labelled deposited in [i, j) (j if none).
std::size_t labelledStop(const std::vector<TrackPoint>& pts, std::size_t i, std::size_t j) {
  std::size_t k = j;
  while (k > i && pts[k - 1].state == "deposited") --k;
  return k;
}

}  // namespace

RestWindow restWindow(const std::vector<TrackPoint>& pts, std::size_t b, std::size_t j, double distance) {
  RestWindow w;
  if (j <= b) return w;
  double moved = 0;
  for (std::size_t k = b; k < j; ++k) moved = std::max(moved, std::hypot(pts[k].x - pts[j - 1].x, pts[k].y - pts[j - 1].y));
  if (moved < distance) {
    w.at_rest = w.exact = true;
    return w;
  }
  // Noisy positions (a tracker's, where the distance may be below its localisation error
  // sigma): at rest means that the window's first and last thirds have medians within
  // distance + 3 sigma, and that 90 % of its points lie within that of the window's median
  // (a neighbour passing by or depositing alongside shifts a few centroids). A particle moving
  // at v px/frame has sigma ~ v / 2 by this estimate, so any steady motion over the window's 6
  // or more points fails the first test.
  const std::size_t n = j - b;
  if (n < 6) return w;
  const double tol = distance + 3.0 * restingNoise(pts, b, j);
  const std::size_t m = n / 3;
  double ax, ay, bx, by, mx, my;
  medianOf(pts, b, b + m, ax, ay);
  medianOf(pts, j - m, j, bx, by);
  if (std::hypot(bx - ax, by - ay) > tol) return w;
  medianOf(pts, b, j, mx, my);
  std::size_t outside = 0;
  for (std::size_t k = b; k < j; ++k) outside += std::hypot(pts[k].x - mx, pts[k].y - my) > tol ? 1 : 0;
  w.at_rest = outside * 10 <= n;
  w.centre_x = mx;
  w.centre_y = my;
  w.radius = tol;
  return w;
}

bool isStopped(const std::vector<TrackPoint>& pts, std::size_t i, std::size_t j, const TrackOptions& o) {
  if (j <= i + 1 || pts[j - 1].t - pts[i].t < o.stuck_window) return false;
  return restWindow(pts, windowBegin(pts, i, j, o), j, o.stuck_distance).at_rest;
}

std::size_t stopIndex(const std::vector<TrackPoint>& pts, std::size_t i, std::size_t j, const TrackOptions& o) {
  const std::size_t b = windowBegin(pts, i, j, o);
  double mx, my;
  medianOf(pts, b, j, mx, my);
  const double r = o.stuck_distance + 3.0 * restingNoise(pts, b, j);
  // Back from the end while points stay near the resting place; a single stray point (a
  // neighbour's centroid) does not end the stretch, two in a row do.
  std::size_t k = j - 1;
  while (k > i) {
    if (std::hypot(pts[k - 1].x - mx, pts[k - 1].y - my) <= r) {
      --k;
    } else if (k > i + 1 && std::hypot(pts[k - 2].x - mx, pts[k - 2].y - my) <= r) {
      k -= 2;
    } else {
      break;
    }
  }
  return k;
}

namespace {

/// Whether successive steps of points [b, e) anticorrelate as localisation noise about a
/// fixed place does (steps n_k - n_(k-1): lag-1 correlation -1/2), not as a random walk
/// (0) or a creep (> 0). isStopped's noise estimate comes from the steps themselves, so
/// it cannot tell a Brownian particle (D = 0.8 px^2/frame) from a noisy rest; this does.
/// Needs 40 steps: the correlation's standard error is ~1/sqrt(n), and with 20 (a 2 s
/// window at 10 fps) a random walk passes often enough to bias the MSD of a Brownian
/// video by 10 % (TrackingValidation.BrownianDiffusionFromAVideo).
bool incrementsAnticorrelated(const std::vector<TrackPoint>& pts, std::size_t b, std::size_t e) {
  if (e < b + 41) return false;
  double num = 0, den = 0;
  for (std::size_t k = b + 1; k < e; ++k) {
    const double dx = pts[k].x - pts[k - 1].x, dy = pts[k].y - pts[k - 1].y;
    den += dx * dx + dy * dy;
    if (k + 1 < e) num += dx * (pts[k + 1].x - pts[k].x) + dy * (pts[k + 1].y - pts[k].y);
  }
  return den > 0 && num / den <= -0.25;
}

/// Labels "deposited" the points of [i, j) that rest: those of every window of
/// stuck_window that isStopped (ending before the track's last point; the trailing rest
/// is markDeposits' own case) and that lie within its resting radius (stuck_distance + 3
/// sigma) of its median. Tracked deposits do leave: a passing particle that hides a
/// deposit for a frame or two takes over the deposit's track (or the deposit takes the
/// passer's), and the track moves on. Unlabelled, the rest's hundreds of localisation-noise
/// steps (~0.1-0.3 px/frame) went into the velocity statistics, where simulated
/// trajectories, which end where a particle attaches, have none. Deposits sit on grain
/// walls, mostly in throats: this pulled the tracked throat speed 20 % low in
/// compare-micromodel-regions. The union of windows, not one stretch per rest: a
/// neighbour depositing alongside shifts a resting centroid by a few tenths of a pixel.
void markInteriorRests(std::vector<TrackPoint>& pts, std::size_t i, std::size_t j, const TrackOptions& o) {
  std::vector<char> stopped(j - i + 1, 0), rest(j - i, 0);
  for (std::size_t e = i + 2; e < j; ++e)
    stopped[e - i] = pts[e - 1].t - pts[i].t >= o.stuck_window && isStopped(pts, i, e, o) && incrementsAnticorrelated(pts, windowBegin(pts, i, e, o), e);
  auto label = [&](std::size_t e) {
    const std::size_t b = windowBegin(pts, i, e, o);
    double mx, my;
    medianOf(pts, b, e, mx, my);
    const double r = o.stuck_distance + 3.0 * restingNoise(pts, b, e);
    for (std::size_t k = b; k < e; ++k)
      if (std::hypot(pts[k].x - mx, pts[k].y - my) <= r) rest[k - i] = 1;
  };
  // One window at rest is enough: tracked rests at deposit clusters are broken every
  // few seconds by a neighbour's centroid, so two successive windows at rest miss most
  // of them (throat speed 653 instead of 690 um/s on compare-micromodel-regions). A slow
  // creep passes a window by chance only when the window holds few frames (a 2 s window
  // at 10 fps, 0.05 px/frame under 0.15 px noise); at 40 fps, 0.02 px/frame does not.
  for (std::size_t e = i + 2; e < j; ++e)
    if (stopped[e - i]) label(e);
  for (std::size_t k = i; k < j; ++k)
    if (rest[k - i]) pts[k].state = "deposited";
}

}  // namespace

void markDeposits(Tracks& tracks, const TrackOptions& o) {
  auto& pts = tracks.points;
  for (std::size_t i = 0; i < pts.size();) {
    std::size_t j = i;
    while (j < pts.size() && pts[j].particle == pts[i].particle) ++j;
    double reach = 0;
    for (std::size_t k = i; k < j; ++k) reach = std::max(reach, std::hypot(pts[k].x - pts[i].x, pts[k].y - pts[i].y));
    const bool candidate = static_cast<int>(j - i) >= o.min_points && reach >= o.immobile_distance;
    if (candidate) markInteriorRests(pts, i, j, o);
    if (candidate && pts[j - 1].state != "deposited" && isStopped(pts, i, j, o))
      for (std::size_t k = stopIndex(pts, i, j, o); k < j; ++k) pts[k].state = "deposited";
    i = j;
  }
}

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
  std::vector<const TrackPoint*> mobile_points, mobile_first;
  std::vector<std::size_t> mobile_track;  // index in s.tracks of each mobile_first
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
      mobile_first.push_back(&pts[i]);
      mobile_track.push_back(s.tracks.size());
      for (std::size_t k = i; k < j; ++k)
        if (!restingTail(pts, i, k)) mobile_points.push_back(&pts[k]);
      for (std::size_t k = i + 1; k < j; ++k) {
        const double dt = pts[k].t - pts[k - 1].t;
        if (restingTail(pts, i, k)) continue;
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
      if (pts[j - 1].state == "deposited") {
        ++s.retained;
        ts.stop_time = pts[std::min(labelledStop(pts, i, j), j - 1)].t;
      } else if (isStopped(pts, i, j, o)) {
        ++s.retained;
        ts.stop_time = pts[stopIndex(pts, i, j, o)].t;
      }
      ts.state = s.retained > retained_before ? "deposited" : "mobile";
    }
    s.tracks.push_back(ts);
    i = j;
  }
  // Particles that entered the view: mobile tracks that begin in the first frames or
  // near the edge of the field of view (the box of all positions). A track that begins
  // mid-video in the interior continues a particle already counted (the tracker lost it
  // for longer than its gap closing), so retention, like the experiment's fraction of the
  // injected particles, is retained / entered and does not fall with fragmentation.
  {
    double x0 = std::numeric_limits<double>::max(), y0 = x0, x1 = std::numeric_limits<double>::lowest(), y1 = x1;
    std::vector<double> dts;
    for (std::size_t k = 0; k < pts.size(); ++k) {
      x0 = std::min(x0, pts[k].x);
      x1 = std::max(x1, pts[k].x);
      y0 = std::min(y0, pts[k].y);
      y1 = std::max(y1, pts[k].y);
      if (k > 0 && pts[k].particle == pts[k - 1].particle && pts[k].t > pts[k - 1].t) dts.push_back(pts[k].t - pts[k - 1].t);
    }
    const double frame_dt = dts.empty() ? 0.0 : median(dts);
    const double margin = o.entry_margin * std::min(x1 - x0, y1 - y0);
    for (std::size_t m = 0; m < mobile_first.size(); ++m) {
      const TrackPoint* p = mobile_first[m];
      if (p->t <= s.t_begin + 2.5 * frame_dt || p->x <= x0 + margin || p->x >= x1 - margin || p->y <= y0 + margin || p->y >= y1 - margin) {
        ++s.entered;
        s.tracks[mobile_track[m]].entered = true;
      }
    }
  }
  const int base = s.entered > 0 ? s.entered : s.mobile;
  s.retained_fraction = base > 0 ? std::min(1.0, static_cast<double>(s.retained) / base) : 0.0;
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
  // Moving part only: a deposited particle's resting tail (see analyseTracks) is left out.
  for (std::size_t k = 0; k < tracks.points.size(); ++k) {
    const auto& p = tracks.points[k];
    const bool tail = k > 0 && tracks.points[k - 1].particle == p.particle && p.state == "deposited" && tracks.points[k - 1].state == "deposited";
    if (!tail && state.count(p.particle) && state[p.particle]->state != "immobile") by_particle[p.particle].push_back(&p);
  }
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
