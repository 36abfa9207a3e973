// Retention counted by one rule on any tracks file (Retention.hpp).
#include "mmval/compare/Retention.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "mmval/tracking/Statistics.hpp"

namespace mmval::compare {

namespace {

/// Value below which a share q of v lies (nearest rank); v non-empty.
double quantileOf(std::vector<double> v, double q) {
  const auto k = static_cast<std::size_t>(std::clamp(q, 0.0, 1.0) * static_cast<double>(v.size() - 1) + 0.5);
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

/// Per-axis localisation noise of rows [b, e) from their second differences
/// x(k+1) - 2 x(k) + x(k-1): a steady drift (a crawl) cancels in them, and independent
/// errors of sigma per axis give N(0, 6 sigma^2), whose median absolute value is
/// 0.6745 sqrt(6) sigma. The median, not the mean square, so that a centroid swapped
/// with a passing neighbour for a frame does not inflate it. 0 with fewer than four rows.
double stepNoise(const std::vector<TrackPoint>& p, std::size_t b, std::size_t e) {
  std::vector<double> d;
  for (std::size_t k = b + 1; k + 1 < e; ++k) {
    d.push_back(std::abs(p[k + 1].x - 2 * p[k].x + p[k - 1].x));
    d.push_back(std::abs(p[k + 1].y - 2 * p[k].y + p[k - 1].y));
  }
  if (d.size() < 4) return 0.0;
  return tracking::median(d) / (0.6745 * std::sqrt(6.0));
}

}  // namespace

RestVerdict restAtEnd(const std::vector<TrackPoint>& p, double t_end, double frame_dt, const tracking::TrackOptions& o) {
  RestVerdict v;
  v.drift_speed = std::numeric_limits<double>::quiet_NaN();
  if (p.empty()) return v;
  const double eps = 1e-9 * std::max(1.0, std::abs(t_end));
  const double t_last = p.back().t;
  // Held: ended early on a deposited row; the particle stays at its resting place.
  std::size_t tail = p.size();
  while (tail > 0 && p[tail - 1].state == "deposited") --tail;
  v.held = tail < p.size() && frame_dt > 0 && t_end - t_last > 0.5 * frame_dt;
  std::vector<TrackPoint> w(p.begin(), p.end());
  if (v.held) {
    std::vector<double> xs, ys;
    for (std::size_t k = tail; k < p.size(); ++k) {
      xs.push_back(p[k].x);
      ys.push_back(p[k].y);
    }
    TrackPoint rest = p.back();
    rest.x = tracking::median(xs);
    rest.y = tracking::median(ys);
    for (int k = 1; t_last + k * frame_dt <= t_end + eps; ++k) {
      rest.t = t_last + k * frame_dt;
      ++rest.frame;
      w.push_back(rest);
    }
  }
  const double t_stop = w.back().t;
  // Noise from the track's own steps over its last window of measured rows.
  std::size_t nb = p.size() - 1;
  while (nb > 0 && p[nb - 1].t >= t_last - o.stuck_window - eps) --nb;
  v.noise = stepNoise(p, nb, p.size());
  const double rest_speed = o.stuck_window > 0 ? o.stuck_distance / o.stuck_window : 0.0;
  v.threshold = rest_speed;
  if (t_stop - w.front().t < o.stuck_window - eps) return v;  // too short to show a rest
  std::size_t b = w.size() - 1;
  while (b > 0 && w[b - 1].t >= t_stop - o.stuck_window - eps) --b;
  const std::size_t n = w.size() - b, third = n / 3;
  if (third < 1) return v;
  auto medianPoint = [&](std::size_t from, std::size_t to, double& mx, double& my, double& mt) {
    std::vector<double> xs, ys, ts;
    for (std::size_t k = from; k < to; ++k) {
      xs.push_back(w[k].x);
      ys.push_back(w[k].y);
      ts.push_back(w[k].t);
    }
    mx = tracking::median(xs);
    my = tracking::median(ys);
    mt = tracking::median(ts);
  };
  double ax, ay, at, bx, by, bt;
  medianPoint(b, b + third, ax, ay, at);
  medianPoint(w.size() - third, w.size(), bx, by, bt);
  if (!(bt > at)) return v;
  v.drift_speed = std::hypot(bx - ax, by - ay) / (bt - at);
  // Standard error per axis of that drift: each median of `third` points with noise
  // sigma has 1.2533 sigma / sqrt(third) (the asymptotic standard error of a median).
  const double se = 1.2533 * v.noise * std::sqrt(2.0 / static_cast<double>(third)) / (bt - at);
  v.threshold = rest_speed + 3.0 * se;
  v.at_rest = v.drift_speed < v.threshold;
  if (!v.at_rest) return v;
  // Stop time: back from the end while rows stay nearer the resting place (median of
  // the window) than stuck_distance + 3 sigma; one stray row does not end the stretch.
  double mx, my, mt;
  medianPoint(b, w.size(), mx, my, mt);
  const double r = o.stuck_distance + 3.0 * v.noise;
  auto near = [&](std::size_t k) { return std::hypot(w[k].x - mx, w[k].y - my) < r; };
  std::size_t k = w.size() - 1;
  while (k > 0) {
    if (near(k - 1)) {
      --k;
    } else if (k > 1 && near(k - 2)) {
      k -= 2;
    } else {
      break;
    }
  }
  v.stop_time = w[k].t;
  return v;
}

namespace {

/// One track of the file: rows [b, e) of Tracks::points.
struct Fragment {
  std::size_t b = 0, e = 0;
  bool moving = false;
  int chain = -1;
  bool continued = false;  ///< a later track continues this one
};

struct Chain {
  bool entered = false;
  std::vector<std::size_t> members;  ///< its fragments, in order of time (they do not overlap)
  double t_first = 0;
};

}  // namespace

RetentionCount countRetention(const Tracks& tracks, const RetentionOptions& ro) {
  const auto& o = ro.tracks;
  const auto& pts = tracks.points;
  RetentionCount out;
  out.rest_speed = o.stuck_window > 0 ? o.stuck_distance / o.stuck_window : 0.0;
  out.fraction = std::numeric_limits<double>::quiet_NaN();
  if (pts.empty()) return out;
  double t_begin = pts.front().t, t_end = pts.front().t;
  std::vector<double> dts, speeds, xs, ys;
  std::vector<Fragment> frags;
  for (std::size_t i = 0; i < pts.size();) {
    std::size_t j = i;
    while (j < pts.size() && pts[j].particle == pts[i].particle) ++j;
    double reach = 0;
    for (std::size_t k = i; k < j; ++k) {
      reach = std::max(reach, std::hypot(pts[k].x - pts[i].x, pts[k].y - pts[i].y));
      t_begin = std::min(t_begin, pts[k].t);
      t_end = std::max(t_end, pts[k].t);
      xs.push_back(pts[k].x);
      ys.push_back(pts[k].y);
      if (k > i && pts[k].t > pts[k - 1].t) {
        const double dt = pts[k].t - pts[k - 1].t;
        dts.push_back(dt);
        speeds.push_back(std::hypot(pts[k].x - pts[k - 1].x, pts[k].y - pts[k - 1].y) / dt);
      }
    }
    if (static_cast<int>(j - i) >= o.min_points) frags.push_back({i, j, reach >= o.immobile_distance});
    i = j;
  }
  const double frame_dt = dts.empty() ? 0.0 : tracking::median(dts);
  out.link_speed = speeds.empty() ? 0.0 : quantileOf(speeds, ro.link_speed_quantile);
  cv::Rect2d view;
  if (ro.view) {
    view = *ro.view;
  } else {
    const double x0 = quantileOf(xs, 0.001), x1 = quantileOf(xs, 0.999), y0 = quantileOf(ys, 0.001), y1 = quantileOf(ys, 0.999);
    view = cv::Rect2d(x0, y0, x1 - x0, y1 - y0);
  }
  const double margin = o.entry_margin * std::min(view.width, view.height);
  auto enters = [&](const TrackPoint& q) {
    return q.t <= t_begin + 2.5 * frame_dt || q.x <= view.x + margin || q.x >= view.x + view.width - margin || q.y <= view.y + margin ||
           q.y >= view.y + view.height - margin;
  };
  // Chains, in order of first time: an entering moving track starts one; any other track
  // continues the chain whose open end is nearest its start among those that ended at
  // most link_gap before it, no farther than link_speed x gap + link_slack.
  std::stable_sort(frags.begin(), frags.end(), [&](const Fragment& a, const Fragment& b) { return pts[a.b].t < pts[b.b].t; });
  std::vector<Chain> chains;
  std::vector<std::size_t> open;  // fragments whose end may still be continued
  for (std::size_t f = 0; f < frags.size(); ++f) {
    Fragment& fr = frags[f];
    const TrackPoint& start = pts[fr.b];
    open.erase(std::remove_if(open.begin(), open.end(),
                              [&](std::size_t g) { return frags[g].continued || pts[frags[g].e - 1].t < start.t - ro.link_gap; }),
               open.end());
    if (fr.moving && enters(start)) {
      chains.push_back({true, {f}, start.t});
      fr.chain = static_cast<int>(chains.size()) - 1;
    } else {
      std::size_t best = frags.size();
      double best_d = 0;
      for (std::size_t g : open) {
        const TrackPoint& end = pts[frags[g].e - 1];
        const double gap = start.t - end.t;
        if (gap <= 0) continue;
        const double d = std::hypot(start.x - end.x, start.y - end.y);
        if (d <= out.link_speed * gap + ro.link_slack && (best == frags.size() || d < best_d)) {
          best = g;
          best_d = d;
        }
      }
      if (best < frags.size()) {
        frags[best].continued = true;
        fr.chain = frags[best].chain;
        chains[static_cast<std::size_t>(fr.chain)].members.push_back(f);
        ++out.continued;
      } else if (fr.moving) {
        chains.push_back({false, {f}, start.t});
        fr.chain = static_cast<int>(chains.size()) - 1;
      }
    }
    if (fr.chain >= 0) {
      ++out.tracks;
      open.push_back(f);
    }
  }
  // The rest rule on each chain's rows: a particle whose last track is shorter than the
  // window (the tracker broke it when a neighbour came by) is judged on the rows of its
  // earlier tracks as well.
  for (const Chain& c : chains) {
    std::vector<TrackPoint> rows;
    for (std::size_t m : c.members) rows.insert(rows.end(), pts.begin() + static_cast<std::ptrdiff_t>(frags[m].b), pts.begin() + static_cast<std::ptrdiff_t>(frags[m].e));
    const RestVerdict v = restAtEnd(rows, t_end, frame_dt, o);
    if (!c.entered) {
      ++out.orphans;
      out.orphans_at_rest += v.at_rest ? 1 : 0;
      continue;
    }
    ++out.entered;
    out.entry_times.push_back(c.t_first);
    if (rows.back().state == "deposited") ++out.labelled_deposited;
    if (v.at_rest) {
      ++out.retained;
      out.stop_times.push_back(std::max(v.stop_time, c.t_first));
    }
  }
  if (out.entered > 0) out.fraction = static_cast<double>(out.retained) / out.entered;
  return out;
}

}  // namespace mmval::compare
