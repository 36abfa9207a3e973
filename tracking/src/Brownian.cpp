#include "mmval/tracking/Brownian.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>

#include <gsl/gsl_cdf.h>

#include "mmval/tracking/Statistics.hpp"

namespace mmval::tracking {

const char* motionModelName(MotionModel m) {
  switch (m) {
    case MotionModel::flow: return "flow";
    case MotionModel::brownian: return "brownian";
    case MotionModel::automatic: return "auto";
  }
  return "auto";
}

MotionModel parseMotionModel(const std::string& name) {
  if (name == "flow") return MotionModel::flow;
  if (name == "brownian") return MotionModel::brownian;
  if (name == "auto") return MotionModel::automatic;
  throw std::invalid_argument("motion model '" + name + "': expected flow, brownian or auto");
}

std::vector<std::pair<std::size_t, std::size_t>> trackRanges(const std::vector<TrackPoint>& pts) {
  std::vector<std::pair<std::size_t, std::size_t>> out;
  for (std::size_t i = 0; i < pts.size();) {
    std::size_t j = i;
    while (j < pts.size() && pts[j].particle == pts[i].particle) ++j;
    out.emplace_back(i, j);
    i = j;
  }
  return out;
}

namespace {

/// Weighted least squares line y = a + b x; false with fewer than two distinct x.
bool weightedLine(const std::vector<double>& x, const std::vector<double>& y, const std::vector<double>& w, double& a, double& b) {
  double sw = 0, sx = 0, sy = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    sw += w[i];
    sx += w[i] * x[i];
    sy += w[i] * y[i];
  }
  if (!(sw > 0)) return false;
  const double mx = sx / sw, my = sy / sw;
  double sxx = 0, sxy = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    sxx += w[i] * (x[i] - mx) * (x[i] - mx);
    sxy += w[i] * (x[i] - mx) * (y[i] - my);
  }
  if (!(sxx > 0)) return false;
  b = sxy / sxx;
  a = my - b * mx;
  return true;
}

/// Squared displacements per lag 1..max_lag, summed over tracks in groups (for the jackknife).
struct LagSums {
  int groups = 0, max_lag = 0;
  std::vector<std::vector<double>> sum;     ///< [group][lag]
  std::vector<std::vector<long long>> n;    ///< [group][lag]
  std::vector<double> total_sum;
  std::vector<long long> total_n;
  double msd(int lag, int without) const {
    const double s = total_sum[lag] - (without >= 0 ? sum[without][lag] : 0.0);
    const long long c = total_n[lag] - (without >= 0 ? n[without][lag] : 0);
    return c > 0 ? s / static_cast<double>(c) : kNaN;
  }
};

struct FitResult {
  double d = kNaN, offset = kNaN, alpha = kNaN, k = kNaN;
};

/// The two fits of fitEnsembleMsd on the sums without group `without` (-1: all).
FitResult fitSums(const LagSums& s, int without, int lags_d, int lags_alpha, double dt, const std::vector<double>& weight, bool with_alpha) {
  FitResult r;
  std::vector<double> x, y, w;
  for (int lag = 1; lag <= lags_d; ++lag) {
    x.push_back(lag * dt);
    y.push_back(s.msd(lag, without));
    w.push_back(weight[lag]);
  }
  double a = 0, b = 0;
  if (!weightedLine(x, y, w, a, b)) return r;
  r.d = b / 4.0;
  r.offset = a;
  // Exponent: MSD = c + 4 K t^alpha with its own offset c. For a given alpha, c and K
  // are a weighted linear fit against t^alpha (variable projection); alpha minimises
  // the weighted residual (golden section on [0.05, 2.5]).
  x.clear();
  y.clear();
  w.clear();
  for (int lag = 1; lag <= lags_alpha; ++lag) {
    x.push_back(lag * dt);
    y.push_back(s.msd(lag, without));
    w.push_back(weight[lag]);
  }
  if (!with_alpha || lags_alpha < 3) return r;
  std::vector<double> ta(x.size());
  auto residual = [&](double alpha, double& c, double& k4) {
    for (std::size_t i = 0; i < x.size(); ++i) ta[i] = std::pow(x[i] / x.back(), alpha);  // scaled: t^alpha near 1
    if (!weightedLine(ta, y, w, c, k4)) return kNaN;
    double rss = 0;
    for (std::size_t i = 0; i < x.size(); ++i) rss += w[i] * std::pow(y[i] - c - k4 * ta[i], 2);
    return rss;
  };
  const double g = 0.5 * (std::sqrt(5.0) - 1.0);
  double lo = 0.05, hi = 2.5, c = 0, k4 = 0;
  double m1 = hi - g * (hi - lo), m2 = lo + g * (hi - lo);
  double f1 = residual(m1, c, k4), f2 = residual(m2, c, k4);
  for (int it = 0; it < 60 && std::isfinite(f1) && std::isfinite(f2); ++it) {
    if (f1 < f2) {
      hi = m2;
      m2 = m1;
      f2 = f1;
      m1 = hi - g * (hi - lo);
      f1 = residual(m1, c, k4);
    } else {
      lo = m1;
      m1 = m2;
      f1 = f2;
      m2 = lo + g * (hi - lo);
      f2 = residual(m2, c, k4);
    }
  }
  const double alpha = 0.5 * (lo + hi);
  if (std::isfinite(residual(alpha, c, k4))) {
    r.alpha = alpha;
    r.k = k4 / std::pow(x.back(), alpha) / 4.0;
  }
  return r;
}

/// Delete-a-group jackknife standard error of `values` (one per left-out group).
double jackknifeSe(const std::vector<double>& values) {
  std::vector<double> v;
  for (double x : values)
    if (std::isfinite(x)) v.push_back(x);
  const double g = static_cast<double>(v.size());
  if (v.size() < 2) return kNaN;
  const double m = mean(v);
  double ss = 0;
  for (double x : v) ss += (x - m) * (x - m);
  return std::sqrt((g - 1) / g * ss);
}

}  // namespace

double frameInterval(const Tracks& tracks) {
  std::vector<double> dts;
  const auto& p = tracks.points;
  for (std::size_t k = 1; k < p.size(); ++k)
    if (p[k].particle == p[k - 1].particle && p[k].frame > p[k - 1].frame && p[k].t > p[k - 1].t)
      dts.push_back((p[k].t - p[k - 1].t) / static_cast<double>(p[k].frame - p[k - 1].frame));
  return dts.empty() ? kNaN : median(dts);
}

void EnsembleDrift::at(std::int64_t f, double& dx, double& dy) const {
  dx = dy = 0;
  const auto it = std::upper_bound(frame.begin(), frame.end(), f);
  if (it == frame.begin()) return;
  const auto k = static_cast<std::size_t>(it - frame.begin() - 1);
  dx = x[k];
  dy = y[k];
}

EnsembleDrift ensembleDrift(const Tracks& tracks, const std::unordered_set<std::int64_t>& excluded) {
  EnsembleDrift d;
  const auto& p = tracks.points;
  std::map<std::int64_t, double> time;
  for (const auto& q : p) time.emplace(q.frame, q.t);
  for (const auto& [f, t] : time) {
    d.frame.push_back(f);
    d.t.push_back(t);
  }
  const std::size_t n = d.frame.size();
  std::vector<double> sx(n, 0), sy(n, 0);
  d.pairs.assign(n, 0);
  auto index = [&](std::int64_t f) { return static_cast<std::size_t>(std::lower_bound(d.frame.begin(), d.frame.end(), f) - d.frame.begin()); };
  for (std::size_t k = 1; k < p.size(); ++k) {
    if (p[k].particle != p[k - 1].particle || excluded.count(p[k].particle)) continue;
    const std::size_t i = index(p[k].frame);
    if (i == 0 || d.frame[i - 1] != p[k - 1].frame) continue;  // only steps between neighbouring frames
    sx[i] += p[k].x - p[k - 1].x;
    sy[i] += p[k].y - p[k - 1].y;
    ++d.pairs[i];
  }
  d.x.assign(n, 0);
  d.y.assign(n, 0);
  for (std::size_t i = 1; i < n; ++i) {
    d.x[i] = d.x[i - 1] + (d.pairs[i] > 0 ? sx[i] / d.pairs[i] : 0.0);
    d.y[i] = d.y[i - 1] + (d.pairs[i] > 0 ? sy[i] / d.pairs[i] : 0.0);
  }
  return d;
}

Tracks driftCorrected(const Tracks& tracks, const EnsembleDrift& drift) {
  Tracks out = tracks;
  for (auto& q : out.points) {
    double dx, dy;
    drift.at(q.frame, dx, dy);
    q.x -= dx;
    q.y -= dy;
  }
  return out;
}

MsdFit fitEnsembleMsd(const Tracks& tracks, double dt, const BrownianOptions& o) {
  MsdFit out;
  const auto& pts = tracks.points;
  const auto sp = trackRanges(pts);
  out.tracks = static_cast<int>(sp.size());
  if (sp.empty() || !(dt > 0)) return out;
  std::vector<std::int64_t> lengths;
  std::int64_t longest = 0;
  for (const auto& [i, j] : sp) {
    lengths.push_back(static_cast<std::int64_t>(j - i));
    longest = std::max(longest, pts[j - 1].frame - pts[i].frame);
  }
  std::vector<double> len_d(lengths.begin(), lengths.end());
  const int median_len = static_cast<int>(median(len_d));
  const int fit_cap = o.max_lag > 0 ? o.max_lag : 20;
  const int max_lag = static_cast<int>(std::min<std::int64_t>(longest, std::max(fit_cap, std::max(4, median_len / 4))));
  if (max_lag < 1) return out;
  LagSums s;
  s.groups = static_cast<int>(std::min<std::size_t>(100, sp.size()));
  s.max_lag = max_lag;
  s.sum.assign(s.groups, std::vector<double>(max_lag + 1, 0.0));
  s.n.assign(s.groups, std::vector<long long>(max_lag + 1, 0));
  std::vector<double> gx, gy;
  std::vector<char> has;
  for (std::size_t ti = 0; ti < sp.size(); ++ti) {
    const auto [i, j] = sp[ti];
    const std::int64_t f0 = pts[i].frame, span = pts[j - 1].frame - f0 + 1;
    gx.assign(static_cast<std::size_t>(span), 0);
    gy.assign(static_cast<std::size_t>(span), 0);
    has.assign(static_cast<std::size_t>(span), 0);
    for (std::size_t k = i; k < j; ++k) {
      const auto at = static_cast<std::size_t>(pts[k].frame - f0);
      gx[at] = pts[k].x;
      gy[at] = pts[k].y;
      has[at] = 1;
    }
    auto& gs = s.sum[ti % s.groups];
    auto& gn = s.n[ti % s.groups];
    for (int lag = 1; lag <= max_lag && lag < span; ++lag)
      for (std::int64_t a = 0; a + lag < span; ++a) {
        const auto u = static_cast<std::size_t>(a), v = static_cast<std::size_t>(a + lag);
        if (!has[u] || !has[v]) continue;
        gs[lag] += (gx[v] - gx[u]) * (gx[v] - gx[u]) + (gy[v] - gy[u]) * (gy[v] - gy[u]);
        ++gn[lag];
      }
  }
  s.total_sum.assign(max_lag + 1, 0.0);
  s.total_n.assign(max_lag + 1, 0);
  for (int g = 0; g < s.groups; ++g)
    for (int lag = 1; lag <= max_lag; ++lag) {
      s.total_sum[lag] += s.sum[g][lag];
      s.total_n[lag] += s.n[g][lag];
    }
  // Lags up to the first without a displacement.
  int available = 0;
  while (available < max_lag && s.total_n[available + 1] > 0) ++available;
  std::vector<double> weight(available + 1, 1.0);
  bool weighted = true;
  for (int lag = 1; lag <= available; ++lag) {
    std::vector<double> jk;
    for (int g = 0; g < s.groups; ++g) jk.push_back(s.msd(lag, g));
    const double se = jackknifeSe(jk);
    out.lag.push_back(lag * dt);
    out.msd.push_back(s.msd(lag, -1));
    out.msd_se.push_back(se);
    out.samples.push_back(s.total_n[lag]);
    if (std::isfinite(se) && se > 0)
      weight[lag] = 1.0 / (se * se);
    else
      weighted = false;
  }
  // Weights from the relative variance of each lag times a smooth MSD (an unweighted
  // power law through all lags), not 1 / variance itself: a lag whose MSD came out low
  // has a low variance too (variance ~ MSD^2), and weighting by it pulls D and alpha low.
  if (weighted) {
    std::vector<double> lx, ly, one;
    for (int lag = 1; lag <= available; ++lag)
      if (out.msd[lag - 1] > 0) {
        lx.push_back(std::log(lag * dt));
        ly.push_back(std::log(out.msd[lag - 1]));
        one.push_back(1.0);
      }
    double la = 0, lb = 0;
    if (weightedLine(lx, ly, one, la, lb)) {
      for (int lag = 1; lag <= available; ++lag) {
        const double m = out.msd[lag - 1], smooth = std::exp(la + lb * std::log(lag * dt));
        weight[lag] = m > 0 ? m * m * weight[lag] / (smooth * smooth) : 0.0;  // 1 / (relative variance x smooth^2)
      }
    }
  } else {
    std::fill(weight.begin(), weight.end(), 1.0);  // no spread to weigh by (a single track)
  }
  if (available < 2) return out;
  const int alpha_lags = std::min(available, std::max(10, median_len / 4));
  auto replicate = [&](int lags_d, int without, bool with_alpha) {
    return fitSums(s, without, lags_d, std::max(alpha_lags, lags_d), dt, weight, with_alpha);
  };
  auto seOfD = [&](int lags_d) {
    std::vector<double> v;
    for (int g = 0; g < s.groups; ++g) v.push_back(replicate(lags_d, g, false).d);
    return jackknifeSe(v);
  };
  int p = std::min(available, o.max_lag > 0 ? o.max_lag : 2);
  if (o.max_lag <= 0) {
    // Michalet 2010: the standard error of D from a fit with an offset first falls with
    // more lags, then rises (long lags are few and correlated); take its minimum.
    double best = seOfD(2);
    for (int q = 3; q <= std::min(available, 20); ++q) {
      const double se = seOfD(q);
      if (std::isfinite(se) && (!std::isfinite(best) || se < best)) {
        best = se;
        p = q;
      }
    }
  }
  out.lags_d = p;
  out.lags_alpha = std::max(alpha_lags, p);
  const FitResult all = replicate(p, -1, true);
  out.d = all.d;
  out.offset = all.offset;
  out.alpha = all.alpha;
  out.k_alpha = all.k;
  out.sigma2 = (all.offset + 4.0 / 3.0 * all.d * o.exposure) / 4.0;
  std::vector<double> ds, offs, s2s, alphas;
  for (int g = 0; g < s.groups; ++g) {
    const FitResult r = replicate(p, g, true);
    ds.push_back(r.d);
    offs.push_back(r.offset);
    s2s.push_back((r.offset + 4.0 / 3.0 * r.d * o.exposure) / 4.0);
    alphas.push_back(r.alpha);
  }
  out.d_se = jackknifeSe(ds);
  out.offset_se = jackknifeSe(offs);
  out.sigma2_se = jackknifeSe(s2s);
  out.alpha_se = jackknifeSe(alphas);
  out.reduced_error = out.d > 0 ? out.sigma2 / (out.d * dt) : kNaN;
  return out;
}

CveEstimate cveEstimate(const std::vector<TrackPoint>& pts, std::size_t first, std::size_t last, double dt, double exposure) {
  CveEstimate e;
  double sq = 0, cov = 0;
  for (std::size_t k = first + 1; k < last; ++k) {
    if (pts[k].frame - pts[k - 1].frame != 1) continue;
    const double dx = pts[k].x - pts[k - 1].x, dy = pts[k].y - pts[k - 1].y;
    sq += dx * dx + dy * dy;
    ++e.steps;
    if (k + 1 < last && pts[k + 1].frame - pts[k].frame == 1) {
      cov += dx * (pts[k + 1].x - pts[k].x) + dy * (pts[k + 1].y - pts[k].y);
      ++e.pairs;
    }
  }
  if (e.steps < 2 || e.pairs < 1 || !(dt > 0)) return e;
  const double r = exposure / (6.0 * dt);
  e.mean_square = sq / (2.0 * e.steps);
  e.covariance = cov / (2.0 * e.pairs);
  e.d = e.mean_square / (2.0 * dt) + e.covariance / dt;
  e.sigma2 = r * e.mean_square + (2.0 * r - 1.0) * e.covariance;
  // At the track's own values: D below 0 is noise about a small D, taken as 0; the
  // apparent noise sigma^2 - 2 R D dt is -<dx_n dx_n+1>.
  const double d0 = std::max(e.d, 0.0);
  const double apparent = std::max(-e.covariance, 0.0);
  e.d_se = std::sqrt(cveVariance(d0, apparent + 2.0 * r * d0 * dt, dt, r, e.steps) / 2.0);
  return e;
}

double cveVariance(double d, double sigma2, double dt, double r, int n) {
  const double s = (sigma2 - 2.0 * r * d * dt) / dt;
  const double nn = static_cast<double>(n);
  return (6.0 * d * d + 4.0 * d * s + 2.0 * s * s) / nn + 4.0 * (d + s) * (d + s) / (nn * nn);
}

ImmobileTest immobileTest(const CveEstimate& e, double d_ensemble, double dt, double level) {
  ImmobileTest t;
  if (!std::isfinite(e.d) || !(dt > 0) || !(d_ensemble > 0)) return t;
  const double z = gsl_cdf_ugaussian_Qinv(level);
  // At rest: <dx^2> = 2 sigma^2, so s = sigma^2 / dt = <dx^2> / (2 dt) (R plays no part at D = 0).
  const double s0 = e.mean_square / (2.0 * dt);
  const double se0 = std::sqrt(cveVariance(0.0, s0 * dt, dt, 0.0, e.steps) / 2.0);
  // Free with the ensemble's D: <dx^2> / (2 dt) = D + s, so s = <dx^2> / (2 dt) - D.
  const double sf = std::max(0.0, e.mean_square / (2.0 * dt) - d_ensemble);
  const double sef = std::sqrt(cveVariance(d_ensemble, sf * dt, dt, 0.0, e.steps) / 2.0);
  t.z_zero = se0 > 0 ? e.d / se0 : kNaN;
  t.z_free = sef > 0 ? (e.d - d_ensemble) / sef : kNaN;
  t.immobile = std::isfinite(t.z_zero) && std::isfinite(t.z_free) && t.z_free < -z && t.z_zero < z;
  return t;
}

}  // namespace mmval::tracking
