// analyseBrownian (Brownian.hpp): the two passes over the tracks, the per-track
// estimates and the van Hove distributions.
#include <algorithm>
#include <cmath>

#include "mmval/tracking/Brownian.hpp"
#include "mmval/tracking/Statistics.hpp"

namespace mmval::tracking {

namespace {

/// Tracks of `tracks` whose particle passes `keep`.
template <class Keep>
Tracks subset(const Tracks& tracks, Keep keep) {
  Tracks out;
  out.source = tracks.source;
  for (const auto& p : tracks.points)
    if (keep(p.particle)) out.points.push_back(p);
  return out;
}

/// Per-track CVE and immobile test of every track of `corrected` against `d_ensemble`.
std::vector<TrackDiffusion> perTrack(const Tracks& corrected, double dt, double d_ensemble, const BrownianOptions& o) {
  std::vector<TrackDiffusion> out;
  const auto& p = corrected.points;
  for (std::size_t i = 0; i < p.size();) {
    std::size_t j = i;
    while (j < p.size() && p[j].particle == p[i].particle) ++j;
    TrackDiffusion t;
    t.particle = p[i].particle;
    t.points = static_cast<int>(j - i);
    if (t.points >= o.min_points) {
      t.cve = cveEstimate(p, i, j, dt, o.exposure);
      t.test = immobileTest(t.cve, d_ensemble, dt, o.immobile_level);
    }
    t.state = !std::isfinite(t.cve.d) ? "short" : t.test.immobile ? "immobile" : "mobile";
    out.push_back(t);
    i = j;
  }
  return out;
}

/// Histogram of the x and y displacements at `lag` frames of `tracks`, against the
/// Gaussian of variance `model_variance` per axis; bins of a tenth of the larger
/// standard deviation over +- 5 of them.
VanHove vanHove(const Tracks& tracks, int lag, double dt, double model_variance) {
  VanHove v;
  v.lag_frames = lag;
  v.lag = lag * dt;
  v.model_variance = model_variance;
  std::vector<double> d;
  const auto& p = tracks.points;
  for (std::size_t i = 0; i < p.size();) {
    std::size_t j = i;
    while (j < p.size() && p[j].particle == p[i].particle) ++j;
    // Points are sorted by frame: the partner lag frames later, if present, by a moving index.
    std::size_t b = i;
    for (std::size_t a = i; a < j; ++a) {
      while (b < j && p[b].frame < p[a].frame + lag) ++b;
      if (b < j && p[b].frame == p[a].frame + lag) {
        d.push_back(p[b].x - p[a].x);
        d.push_back(p[b].y - p[a].y);
      }
    }
    i = j;
  }
  v.samples = static_cast<long long>(d.size());
  if (d.size() < 2) return v;
  double ss = 0;
  for (double x : d) ss += x * x;
  v.variance = ss / static_cast<double>(d.size());
  const double sd = std::sqrt(std::max(v.variance, std::isfinite(model_variance) ? model_variance : 0.0));
  if (!(sd > 0)) return v;
  v.bin_width = sd / 10.0;
  const int half = 50;
  std::vector<long long> count(2 * half, 0);
  for (double x : d) {
    const int k = static_cast<int>(std::floor(x / v.bin_width)) + half;
    if (k >= 0 && k < 2 * half) ++count[static_cast<std::size_t>(k)];
  }
  for (int k = 0; k < 2 * half; ++k) {
    const double c = (k - half + 0.5) * v.bin_width;
    v.centre.push_back(c);
    v.density.push_back(static_cast<double>(count[static_cast<std::size_t>(k)]) / (static_cast<double>(d.size()) * v.bin_width));
    v.gaussian.push_back(model_variance > 0 ? std::exp(-c * c / (2 * model_variance)) / std::sqrt(2 * M_PI * model_variance) : kNaN);
  }
  return v;
}

}  // namespace

BrownianStats analyseBrownian(const Tracks& tracks, const BrownianOptions& o) {
  BrownianStats s;
  s.frame_interval = frameInterval(tracks);
  const double dt = s.frame_interval;
  if (!(dt > 0)) {
    for (const auto& t : perTrack(tracks, dt, kNaN, o)) {
      s.tracks.push_back(t);
      ++s.particles;
      ++s.short_tracks;
    }
    return s;
  }
  // Pass 1: every track.
  std::unordered_set<std::int64_t> excluded;
  EnsembleDrift drift = ensembleDrift(tracks);
  Tracks corrected = driftCorrected(tracks, drift);
  std::unordered_set<std::int64_t> long_enough;
  {
    const auto& p = tracks.points;
    for (std::size_t i = 0; i < p.size();) {
      std::size_t j = i;
      while (j < p.size() && p[j].particle == p[i].particle) ++j;
      if (static_cast<int>(j - i) >= o.min_points) long_enough.insert(p[i].particle);
      i = j;
    }
  }
  MsdFit fit = fitEnsembleMsd(subset(corrected, [&](std::int64_t id) { return long_enough.count(id) > 0; }), dt, o);
  double d_ensemble = fit.d;
  std::vector<TrackDiffusion> per = perTrack(corrected, dt, d_ensemble, o);
  // Pass 2: without the tracks found immobile.
  for (const auto& t : per)
    if (t.test.immobile) excluded.insert(t.particle);
  if (!excluded.empty()) {
    drift = ensembleDrift(tracks, excluded);
    corrected = driftCorrected(tracks, drift);
    fit = fitEnsembleMsd(subset(corrected, [&](std::int64_t id) { return long_enough.count(id) > 0 && excluded.count(id) == 0; }), dt, o);
    if (fit.d > 0) d_ensemble = fit.d;
    per = perTrack(corrected, dt, d_ensemble, o);
  }
  s.drift = drift;
  s.msd = fit;
  s.tracks = per;
  std::vector<double> ds;
  for (const auto& t : s.tracks) {
    ++s.particles;
    if (t.state == "short") {
      ++s.short_tracks;
    } else if (t.state == "immobile") {
      ++s.immobile;
    } else {
      ++s.mobile;
      ds.push_back(t.cve.d);
    }
  }
  if (!ds.empty()) {
    s.cve_mean = mean(ds);
    s.cve_median = median(ds);
    if (ds.size() > 1) {
      double ss = 0;
      for (double d : ds) ss += (d - s.cve_mean) * (d - s.cve_mean);
      s.cve_mean_se = std::sqrt(ss / static_cast<double>(ds.size() - 1) / static_cast<double>(ds.size()));
    }
  }
  const Tracks used = subset(corrected, [&](std::int64_t id) { return long_enough.count(id) > 0 && excluded.count(id) == 0; });
  for (int lag : o.van_hove_lags)
    if (lag >= 1) s.van_hove.push_back(vanHove(used, lag, dt, std::isfinite(fit.d) ? fit.fitAt(lag * dt) / 2.0 : kNaN));
  return s;
}

}  // namespace mmval::tracking
