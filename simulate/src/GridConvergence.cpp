#include "mmval/simulate/GridConvergence.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>

#include <fmt/format.h>

namespace mmval::simulate {

namespace {

/// Fixed-point iteration of Celik et al. Eq. (3)-(5) without its outer absolute value, so that a
/// change growing on refinement shows as p <= 0. NaN when it does not settle.
double solveOrder(double r21, double r32, double e21, double e32, double s) {
  const double lr = std::log(std::abs(e32 / e21));
  double p = lr / std::log(r21);
  for (int k = 0; k < 200; ++k) {
    const double q = (p > 0 && std::abs(r21 - r32) > 1e-12) ? std::log((std::pow(r21, p) - s) / (std::pow(r32, p) - s)) : 0.0;
    const double next = (lr + q) / std::log(r21);
    if (!std::isfinite(next)) return GridConvergence::nan;
    if (std::abs(next - p) < 1e-12 * std::max(1.0, std::abs(p))) return next;
    p = next;
  }
  return GridConvergence::nan;
}

/// Weighted linear least squares of f = f0 + a h^p for a given p (weights w summing to 1);
/// returns the weighted sum of squared residuals.
double fitAt(const std::vector<double>& h, const std::vector<double>& f, const std::vector<double>& w, double p, double& f0, double& a) {
  double mx = 0, my = 0;
  for (std::size_t i = 0; i < h.size(); ++i) {
    mx += w[i] * std::pow(h[i], p);
    my += w[i] * f[i];
  }
  double sxy = 0, sxx = 0;
  for (std::size_t i = 0; i < h.size(); ++i) {
    const double dx = std::pow(h[i], p) - mx;
    sxy += w[i] * dx * (f[i] - my);
    sxx += w[i] * dx * dx;
  }
  a = sxx > 0 ? sxy / sxx : 0;
  f0 = my - a * mx;
  double ss = 0;
  for (std::size_t i = 0; i < h.size(); ++i) ss += w[i] * std::pow(f0 + a * std::pow(h[i], p) - f[i], 2);
  return ss;
}

struct Fit {
  double p = 0, f0 = 0, a = 0, sigma = 0;
};

/// The order minimising the weighted residual: a scan of p on a 0.01 grid over (0, 8], then
/// golden-section refinement around the best node. sigma = sqrt(n sum w r^2 / (n - 3)).
Fit bestFit(const std::vector<double>& h, const std::vector<double>& f, const std::vector<double>& w) {
  double best_p = 0.01, best = std::numeric_limits<double>::infinity(), f0 = 0, a = 0;
  for (int k = 1; k <= 800; ++k) {
    const double p = 0.01 * k, ss = fitAt(h, f, w, p, f0, a);
    if (ss < best) {
      best = ss;
      best_p = p;
    }
  }
  double lo = std::max(1e-3, best_p - 0.01), hi = std::min(8.0, best_p + 0.01);
  const double gr = 0.5 * (std::sqrt(5.0) - 1);
  for (int k = 0; k < 60; ++k) {
    const double c = hi - gr * (hi - lo), d = lo + gr * (hi - lo);
    if (fitAt(h, f, w, c, f0, a) < fitAt(h, f, w, d, f0, a)) hi = d;
    else lo = c;
  }
  Fit r;
  r.p = 0.5 * (lo + hi);
  const double ss = fitAt(h, f, w, r.p, r.f0, r.a);
  const double n = static_cast<double>(h.size());
  r.sigma = std::sqrt(n * ss / (n - 3));
  return r;
}

/// The least-squares part of `g` (four or more levels; h scaled by the finest spacing). As Eca &
/// Hoekstra, two fits, all levels weighed alike and weighed by 1 / h (the fine levels, nearer the
/// asymptotic range, count more); the one with the smaller standard deviation is kept.
void leastSquares(const std::vector<double>& h_in, const std::vector<double>& f, double formal_order, double fine_h, GridConvergence& g) {
  std::vector<double> h, same, fine_first;
  double inv = 0;
  for (const double v : h_in) {
    h.push_back(v / fine_h);  // finest at 1: h^p stays moderate for p up to 8
    inv += fine_h / v;
  }
  for (const double v : h) {
    same.push_back(1.0 / static_cast<double>(h.size()));
    fine_first.push_back(1.0 / v / inv);
  }
  const Fit u = bestFit(h, f, same), wt = bestFit(h, f, fine_first);
  const bool weighted = wt.sigma < u.sigma;
  const Fit& b = weighted ? wt : u;
  const std::vector<double>& w = weighted ? fine_first : same;
  g.has_fit = true;
  g.fit_weighted = weighted;
  g.fit_levels = static_cast<int>(h.size());
  g.fit_order = b.p;
  g.fit_extrapolated = b.f0;
  g.fit_scatter = b.sigma;
  const double fine = g.fine;
  const bool credible = b.p >= 0.5 && b.p <= 2.1;
  double u0 = b.f0, ua = b.a;
  if (!credible) fitAt(h, f, w, formal_order, u0, ua);
  g.fit_order_used = credible ? b.p : formal_order;
  const double unc = (credible ? 1.25 : 3.0) * std::abs(fine - u0) + g.fit_scatter + std::abs(fine - (u0 + ua));
  g.fit_uncertainty = fine != 0 ? unc / std::abs(fine) : GridConvergence::nan;
}

}  // namespace

GridConvergence gridConvergence(const std::vector<double>& h, const std::vector<double>& f, double formal_order) {
  if (h.size() != f.size()) throw std::invalid_argument("gridConvergence: one value per grid spacing");
  GridConvergence g;
  if (f.empty()) throw std::invalid_argument("gridConvergence: no level");
  for (const double v : h)
    if (!(v > 0)) throw std::invalid_argument("gridConvergence: grid spacings must be positive");
  // Finest first.
  std::vector<std::size_t> idx(h.size());
  std::iota(idx.begin(), idx.end(), 0);
  std::sort(idx.begin(), idx.end(), [&](std::size_t a, std::size_t b) { return h[a] < h[b]; });
  for (std::size_t k = 1; k < idx.size(); ++k)
    if (!(h[idx[k]] > h[idx[k - 1]] * (1 + 1e-12))) throw std::invalid_argument("gridConvergence: two levels with the same grid spacing");
  g.fine = f[idx[0]];
  if (f.size() == 1) {
    g.status = "one level";
    g.note = "one level: no convergence estimate (give a ladder of 3 or more)";
    return g;
  }
  const double f1 = f[idx[0]], f2 = f[idx[1]], r21 = h[idx[1]] / h[idx[0]];
  auto twoGrid = [&](const std::string& status, const std::string& why, bool extrapolate) {
    g.status = status;
    g.order_used = formal_order;
    g.safety_factor = 3.0;
    const double rp = std::pow(r21, formal_order);
    if (extrapolate) g.extrapolated = (rp * f1 - f2) / (rp - 1);
    g.gci = f1 != 0 ? 3.0 * std::abs((f1 - f2) / f1) / (rp - 1) : GridConvergence::nan;
    g.note = why;
  };
  if (f1 == f2) {
    g.status = "unchanged";
    g.gci = 0;
    g.extrapolated = f1;
    g.note = "the two finest levels give the same value";
  } else if (f.size() == 2) {
    twoGrid("two levels", fmt::format("two levels: GCI with Fs = 3 and the formal order {:g}, no observed order", formal_order), true);
  } else {
    const double f3 = f[idx[2]], r32 = h[idx[2]] / h[idx[1]];
    const double e21 = f2 - f1, e32 = f3 - f2;
    const double s = (e32 / e21) >= 0 ? 1.0 : -1.0;
    const double p = e32 != 0 && s > 0 ? solveOrder(r21, r32, e21, e32, s) : GridConvergence::nan;
    if (e32 == 0 || s < 0) {
      twoGrid("oscillatory",
              fmt::format("the three finest levels do not converge monotonically ({:.6g}, {:.6g}, {:.6g}, finest last): no observed order; "
                          "GCI with Fs = 3 and the formal order {:g}",
                          f3, f2, f1, formal_order),
              false);
    } else if (!(p > 0)) {
      twoGrid("diverging",
              fmt::format("the change grows on refinement ({:.6g} -> {:.6g} -> {:.6g}): not in the asymptotic range, no observed order; "
                          "GCI with Fs = 3 and the formal order {:g}",
                          f3, f2, f1, formal_order),
              false);
    } else {
      g.status = "monotone";
      g.has_order = true;
      g.observed_order = p;
      g.order_used = p;
      g.safety_factor = 1.25;
      const double rp = std::pow(r21, p);
      g.extrapolated = (rp * f1 - f2) / (rp - 1);
      g.gci = f1 != 0 ? 1.25 * std::abs((f1 - f2) / f1) / (rp - 1) : GridConvergence::nan;
      g.note = fmt::format("monotone convergence, observed order {:.2f} from the three finest levels", p);
    }
  }
  if (f.size() >= 4) {
    std::vector<double> hs, fs;
    for (const std::size_t i : idx) {
      hs.push_back(h[i]);
      fs.push_back(f[i]);
    }
    leastSquares(hs, fs, formal_order, hs.front(), g);
    // The three finest levels decide while they give a credible order (0.5 to twice the formal
    // order); where they give none, or one beyond that (scatter between nearly equal values), the
    // fit over every level stands for the ladder. On clean ladders whose coarsest level is not yet
    // asymptotic (the disc packings from 0.5 cells per pixel) the three finest are the better guide.
    const bool three_credible = g.has_order && g.observed_order >= 0.5 && g.observed_order <= 2 * formal_order;
    if (!three_credible && g.fit_order > 0.05 && g.fit_order < 7.9 && std::isfinite(g.fit_uncertainty)) {
      const std::string three = g.note;
      g.status = "least squares";
      g.has_order = true;
      g.observed_order = g.fit_order;
      g.order_used = g.fit_order_used;
      g.safety_factor = g.fit_order_used == g.fit_order ? 1.25 : 3.0;
      g.extrapolated = g.fit_extrapolated;
      g.gci = g.fit_uncertainty;
      g.note = fmt::format("least squares over all {} levels{} (Eca & Hoekstra 2014): order {:.2f}, extrapolated {:.6g}, scatter {:.3g}, "
                           "uncertainty {:.3g} % of the finest; the three finest alone: {}",
                           g.fit_levels, g.fit_weighted ? ", weighed by 1/h" : "", g.fit_order, g.fit_extrapolated, g.fit_scatter,
                           100 * g.fit_uncertainty, three);
    } else {
      g.note += fmt::format("; least squares over all {} levels{} (Eca & Hoekstra 2014): order {:.2f}, extrapolated {:.6g}, scatter {:.3g}{}",
                            g.fit_levels, g.fit_weighted ? ", weighed by 1/h" : "", g.fit_order, g.fit_extrapolated, g.fit_scatter,
                            three_credible ? "" : " (its order at the end of (0, 8]: not used)");
    }
  }
  if (std::isfinite(g.gci)) {
    g.band_lo = g.fine - g.gci * std::abs(g.fine);
    g.band_hi = g.fine + g.gci * std::abs(g.fine);
  }
  return g;
}

}  // namespace mmval::simulate
