#include "mmval/tracking/Score.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <unordered_map>

#include "mmval/tracking/Assignment.hpp"

namespace mmval::tracking {

namespace {

struct TrackView {
  std::int64_t id;
  std::map<std::int64_t, std::pair<double, double>> at;  // frame -> (x, y) px
};

std::vector<TrackView> views(const Tracks& t) {
  std::vector<TrackView> out;
  std::unordered_map<std::int64_t, std::size_t> index;
  for (const auto& p : t.points) {
    auto it = index.find(p.particle);
    if (it == index.end()) {
      it = index.emplace(p.particle, out.size()).first;
      out.push_back({p.particle, {}});
    }
    out[it->second].at[p.frame] = {p.x_px, p.y_px};
  }
  return out;
}

}  // namespace

Scores scoreTracks(const Tracks& truth, const Tracks& estimated, double gate, double localisation_gate) {
  const auto X = views(truth), Y = views(estimated);
  Scores s;
  s.truth_tracks = static_cast<int>(X.size());
  s.estimated_tracks = static_cast<int>(Y.size());
  // Candidate pairs: tracks that come within the gate at some shared frame.
  std::map<std::int64_t, std::vector<std::pair<int, std::pair<double, double>>>> truth_by_frame;
  for (int i = 0; i < static_cast<int>(X.size()); ++i)
    for (const auto& [f, xy] : X[i].at) truth_by_frame[f].push_back({i, xy});
  std::map<std::pair<int, int>, double> d;  // (i, j) -> track distance
  for (int j = 0; j < static_cast<int>(Y.size()); ++j)
    for (const auto& [f, xy] : Y[j].at) {
      auto it = truth_by_frame.find(f);
      if (it == truth_by_frame.end()) continue;
      for (const auto& [i, txy] : it->second)
        if (std::hypot(txy.first - xy.first, txy.second - xy.second) < gate) d[{i, j}] = 0;
    }
  for (auto& [ij, dist] : d) {
    const auto& a = X[ij.first].at;
    const auto& b = Y[ij.second].at;
    std::size_t shared = 0;
    double sum = 0;
    for (const auto& [f, xy] : a) {
      auto it = b.find(f);
      if (it == b.end()) continue;
      ++shared;
      sum += std::min(std::hypot(xy.first - it->second.first, xy.second - it->second.second), gate);
    }
    dist = sum + gate * static_cast<double>(a.size() + b.size() - 2 * shared);
  }
  // Optimal pairing per connected component; dummy = leave the truth track unpaired.
  const int n = static_cast<int>(X.size()), m = static_cast<int>(Y.size());
  std::vector<int> parent(n + m);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  for (const auto& [ij, dist] : d) parent[find(ij.first)] = find(n + ij.second);
  std::map<int, std::vector<std::pair<int, int>>> comps;
  for (const auto& [ij, dist] : d) comps[find(ij.first)].push_back(ij);
  std::vector<int> pair_of(n, -1);
  for (const auto& [root, edges] : comps) {
    std::vector<int> rows, cols;
    for (const auto& [i, j] : edges) {
      rows.push_back(i);
      cols.push_back(j);
    }
    std::sort(rows.begin(), rows.end());
    rows.erase(std::unique(rows.begin(), rows.end()), rows.end());
    std::sort(cols.begin(), cols.end());
    cols.erase(std::unique(cols.begin(), cols.end()), cols.end());
    const int r = static_cast<int>(rows.size()), c = static_cast<int>(cols.size());
    std::vector<std::vector<double>> cost(r, std::vector<double>(c + r, kForbidden));
    std::map<int, int> ri, ci;
    for (int k = 0; k < r; ++k) ri[rows[k]] = k;
    for (int k = 0; k < c; ++k) ci[cols[k]] = k;
    for (const auto& [i, j] : edges) cost[ri[i]][ci[j]] = d.at({i, j});
    for (int k = 0; k < r; ++k) cost[k][c + k] = gate * static_cast<double>(X[rows[k]].at.size());
    const auto a = solveAssignment(cost);
    for (int k = 0; k < r; ++k)
      if (a[k] >= 0 && a[k] < c) pair_of[rows[k]] = cols[a[k]];
  }
  double dXY = 0, dX0 = 0, dY0 = 0, se = 0, se_local = 0;
  std::vector<char> y_paired(m, 0);
  long long truth_points = 0, est_points = 0;
  for (const auto& x : X) truth_points += static_cast<long long>(x.at.size());
  for (const auto& y : Y) est_points += static_cast<long long>(y.at.size());
  for (int i = 0; i < n; ++i) {
    dX0 += gate * static_cast<double>(X[i].at.size());
    if (pair_of[i] < 0) {
      dXY += gate * static_cast<double>(X[i].at.size());
      continue;
    }
    y_paired[pair_of[i]] = 1;
    ++s.paired_tracks;
    dXY += d.at({i, pair_of[i]});
    for (const auto& [f, xy] : X[i].at) {
      auto it = Y[pair_of[i]].at.find(f);
      if (it == Y[pair_of[i]].at.end()) continue;
      const double e = std::hypot(xy.first - it->second.first, xy.second - it->second.second);
      if (e < gate) {
        ++s.tp;
        se += e * e;
        if (e < localisation_gate)
          se_local += e * e;
        else
          ++s.gross_points;
      }
    }
  }
  for (int j = 0; j < m; ++j)
    if (!y_paired[j]) dY0 += gate * static_cast<double>(Y[j].at.size());
  s.fn = truth_points - s.tp;
  s.fp = est_points - s.tp;
  s.alpha = dX0 > 0 ? 1 - dXY / dX0 : 0;
  s.beta = dX0 + dY0 > 0 ? (dX0 - dXY) / (dX0 + dY0) : 0;
  s.jaccard_points = s.tp + s.fp + s.fn > 0 ? static_cast<double>(s.tp) / static_cast<double>(s.tp + s.fp + s.fn) : 0;
  const int unpaired_y = m - s.paired_tracks;
  const int unpaired_x = n - s.paired_tracks;
  s.jaccard_tracks = n + unpaired_y > 0 ? static_cast<double>(s.paired_tracks) / (s.paired_tracks + unpaired_x + unpaired_y) : 0;
  s.rmse_px = s.tp > 0 ? std::sqrt(se / static_cast<double>(s.tp)) : 0;
  const long long local = s.tp - s.gross_points;
  s.rmse_localisation_px = local > 0 ? std::sqrt(se_local / static_cast<double>(local)) : 0;
  return s;
}

nlohmann::json scoresJson(const Scores& s) {
  return {{"alpha", s.alpha},
          {"beta", s.beta},
          {"jaccard_points", s.jaccard_points},
          {"jaccard_tracks", s.jaccard_tracks},
          {"rmse_px", s.rmse_px},
          {"rmse_localisation_px", s.rmse_localisation_px},
          {"gross_points", s.gross_points},
          {"tp", s.tp},
          {"fp", s.fp},
          {"fn", s.fn},
          {"truth_tracks", s.truth_tracks},
          {"estimated_tracks", s.estimated_tracks}};
}

void addScoreMetrics(const Scores& s, std::map<std::string, double>& metrics) {
  metrics["jaccard_points"] = s.jaccard_points;
  metrics["jaccard_tracks"] = s.jaccard_tracks;
  metrics["rmse"] = s.rmse_px;
  metrics["rmse_localisation"] = s.rmse_localisation_px;
  metrics["gross_points"] = static_cast<double>(s.gross_points);
}

double immobileRecall(const Tracks& truth, const std::vector<std::int64_t>& immobile_ids, const Tracks& estimated, const TrackStats& stats,
                      double gate) {
  if (immobile_ids.empty()) return 1.0;
  // First point of every estimated immobile track.
  std::unordered_map<std::int64_t, char> immobile;
  for (const auto& t : stats.tracks)
    if (t.state == "immobile") immobile[t.particle] = 1;
  std::vector<std::pair<double, double>> starts;
  std::int64_t last = -1;
  bool first = true;
  for (const auto& p : estimated.points) {
    if (!first && p.particle == last) continue;
    first = false;
    last = p.particle;
    if (immobile.count(p.particle)) starts.push_back({p.x_px, p.y_px});
  }
  int hit = 0;
  for (auto id : immobile_ids) {
    const auto tp = std::find_if(truth.points.begin(), truth.points.end(), [&](const TrackPoint& p) { return p.particle == id; });
    if (tp == truth.points.end()) continue;
    for (const auto& [x, y] : starts)
      if (std::hypot(x - tp->x_px, y - tp->y_px) < gate) {
        ++hit;
        break;
      }
  }
  return static_cast<double>(hit) / static_cast<double>(immobile_ids.size());
}

}  // namespace mmval::tracking
