#include "mmval/tracking/Link.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <unordered_map>

#include "DetectionGrid.hpp"
#include "mmval/tracking/Assignment.hpp"

namespace mmval::tracking {

using detail::DetectionGrid;

namespace {

struct Candidate {
  int track, det;
  double cost;
};

}  // namespace

void TrackLinker::push(int frame, const std::vector<Detection>& dets) {
  // Forget tracks beyond memory.
  m_active.erase(std::remove_if(m_active.begin(), m_active.end(), [&](const Track& t) { return frame - t.last_frame > m_o.memory + 1; }),
                 m_active.end());
  const DetectionGrid grid(dets, m_o.search_radius);
  // Velocities for the prediction: the track's own, or for a track without one the mean of
  // the tracks with one within neighbour_radius.
  std::vector<double> pvx(m_active.size(), 0.0), pvy(m_active.size(), 0.0);
  std::vector<char> predicted(m_active.size(), 0);
  const bool own = m_o.predict != Prediction::none;
  const bool borrow = m_o.predict == Prediction::neighbours || m_o.predict == Prediction::automatic;
  if (own) {
    for (int ti = 0; ti < static_cast<int>(m_active.size()); ++ti) {
      const Track& t = m_active[ti];
      if (!t.has_velocity) continue;
      pvx[ti] = t.vx;
      pvy[ti] = t.vy;
      predicted[ti] = 1;
    }
    if (borrow && m_o.neighbour_radius > 0) {
      std::vector<Detection> moving;  // positions of the tracks with a velocity, for the radius search
      std::vector<int> moving_track;
      for (int ti = 0; ti < static_cast<int>(m_active.size()); ++ti) {
        if (!m_active[ti].has_velocity) continue;
        Detection d;
        d.x = m_active[ti].x;
        d.y = m_active[ti].y;
        moving.push_back(d);
        moving_track.push_back(ti);
      }
      const DetectionGrid neighbours(moving, m_o.neighbour_radius);
      for (int ti = 0; ti < static_cast<int>(m_active.size()); ++ti) {
        if (predicted[ti]) continue;
        double sx = 0, sy = 0;
        int n = 0;
        neighbours.near(m_active[ti].x, m_active[ti].y, m_o.neighbour_radius, [&](int k, double) {
          sx += m_active[moving_track[k]].vx;
          sy += m_active[moving_track[k]].vy;
          ++n;
        });
        if (n == 0) continue;
        pvx[ti] = sx / n;
        pvy[ti] = sy / n;
        predicted[ti] = 1;
        ++m_stats.neighbour_predictions;
      }
    }
  }
  std::vector<Candidate> cands;
  for (int ti = 0; ti < static_cast<int>(m_active.size()); ++ti) {
    const Track& t = m_active[ti];
    const int gap = frame - t.last_frame;
    const double px = t.x + pvx[ti] * gap, py = t.y + pvy[ti] * gap;
    const double radius = m_o.search_radius * (predicted[ti] ? 1.0 : static_cast<double>(gap));
    grid.near(px, py, radius, [&](int di, double dist) {
      double cost;
      if (m_o.method == Linker::paper) {
        // Linear displacement relative to the radius plus the turning angle.
        double angle = 0;
        const double dx = dets[di].x - t.x, dy = dets[di].y - t.y;
        if (t.has_velocity && std::hypot(t.vx, t.vy) > 1e-9 && std::hypot(dx, dy) > 1e-9) {
          const double c = (dx * t.vx + dy * t.vy) / (std::hypot(dx, dy) * std::hypot(t.vx, t.vy));
          angle = std::acos(std::clamp(c, -1.0, 1.0));
        }
        cost = dist / radius + m_o.angle_weight * angle / M_PI;
      } else {
        cost = dist * dist;
      }
      cands.push_back({ti, di, cost});
    });
  }
  std::vector<int> det_to_track(dets.size(), -1);
  if (m_o.method == Linker::paper) {
    std::sort(cands.begin(), cands.end(), [](const Candidate& a, const Candidate& b) { return a.cost < b.cost; });
    std::vector<char> track_used(m_active.size(), 0);
    for (const auto& c : cands)
      if (!track_used[c.track] && det_to_track[c.det] < 0) {
        track_used[c.track] = 1;
        det_to_track[c.det] = c.track;
      }
  } else {
    // Connected components of the bipartite candidate graph (union-find).
    const int nt = static_cast<int>(m_active.size()), nd = static_cast<int>(dets.size());
    std::vector<int> parent(nt + nd);
    std::iota(parent.begin(), parent.end(), 0);
    auto find = [&](int a) {
      while (parent[a] != a) a = parent[a] = parent[parent[a]];
      return a;
    };
    for (const auto& c : cands) parent[find(c.track)] = find(nt + c.det);
    std::unordered_map<int, std::vector<const Candidate*>> comps;
    for (const auto& c : cands) comps[find(c.track)].push_back(&c);
    const double no_link = m_o.search_radius * m_o.search_radius;
    for (auto& [root, list] : comps) {
      std::vector<int> tracks, ds;
      for (const auto* c : list) {
        tracks.push_back(c->track);
        ds.push_back(c->det);
      }
      std::sort(tracks.begin(), tracks.end());
      tracks.erase(std::unique(tracks.begin(), tracks.end()), tracks.end());
      std::sort(ds.begin(), ds.end());
      ds.erase(std::unique(ds.begin(), ds.end()), ds.end());
      m_stats.largest_component = std::max<long long>(m_stats.largest_component, static_cast<long long>(tracks.size() + ds.size()));
      if (static_cast<int>(tracks.size()) > m_o.max_component) {
        ++m_stats.greedy_components;
        std::vector<const Candidate*> sorted = list;
        std::sort(sorted.begin(), sorted.end(), [](auto* a, auto* b) { return a->cost < b->cost; });
        std::unordered_map<int, char> used;
        for (const auto* c : sorted)
          if (!used[c->track] && det_to_track[c->det] < 0) {
            used[c->track] = 1;
            det_to_track[c->det] = c->track;
          }
        continue;
      }
      // Rows: tracks; columns: detections, then one "no link" column per track.
      const int r = static_cast<int>(tracks.size()), cnum = static_cast<int>(ds.size()) + r;
      std::vector<std::vector<double>> cost(r, std::vector<double>(cnum, kForbidden));
      std::unordered_map<int, int> ti, di;
      for (int i = 0; i < r; ++i) ti[tracks[i]] = i;
      for (int j = 0; j < static_cast<int>(ds.size()); ++j) di[ds[j]] = j;
      for (const auto* c : list) cost[ti[c->track]][di[c->det]] = std::min(cost[ti[c->track]][di[c->det]], c->cost);
      for (int i = 0; i < r; ++i) cost[i][ds.size() + i] = no_link;
      const auto assign = solveAssignment(cost);
      for (int i = 0; i < r; ++i)
        if (assign[i] >= 0 && assign[i] < static_cast<int>(ds.size()) && cost[i][assign[i]] < kForbidden) det_to_track[ds[assign[i]]] = tracks[i];
    }
  }
  // Apply links, start new tracks.
  for (int di = 0; di < static_cast<int>(dets.size()); ++di) {
    const Detection& d = dets[di];
    if (det_to_track[di] >= 0) {
      Track& t = m_active[det_to_track[di]];
      const int gap = frame - t.last_frame;
      if (gap > 1) ++m_stats.gap_closures;
      // Velocity for the prediction: the last step averaged with the previous estimate
      // (an exponential filter), which halves the localisation noise a single step carries.
      const double vx = (d.x - t.x) / gap, vy = (d.y - t.y) / gap;
      const double keep = t.has_velocity ? m_o.velocity_smoothing : 0.0;
      t.vx = keep * t.vx + (1 - keep) * vx;
      t.vy = keep * t.vy + (1 - keep) * vy;
      t.has_velocity = true;
      t.x = d.x;
      t.y = d.y;
      t.last_frame = frame;
      ++m_stats.links;
      m_points.push_back({frame, t.id, d.x, d.y, d});
    } else {
      m_active.push_back({m_next_id, frame, d.x, d.y});
      ++m_stats.new_tracks;
      m_points.push_back({frame, m_next_id++, d.x, d.y, d});
    }
  }
}

std::vector<LinkedPoint> TrackLinker::points() const {
  std::vector<LinkedPoint> out = m_points;
  std::stable_sort(out.begin(), out.end(), [](const LinkedPoint& a, const LinkedPoint& b) {
    return a.particle != b.particle ? a.particle < b.particle : a.frame < b.frame;
  });
  return out;
}

}  // namespace mmval::tracking
