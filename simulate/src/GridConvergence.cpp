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

/// Linear least squares of f = f0 + a h^p for a given p; returns the residuals' sum of squares.
double fitAt(const std::vector<double>& h, const std::vector<double>& f, double p, double& f0, double& a) {
  const double n = static_cast<double>(h.size());
  double mx = 0, my = 0;
  for (std::size_t i = 0; i < h.size(); ++i) {
    mx += std::pow(h[i], p) / n;
    my += f[i] / n;
  }
  double sxy = 0, sxx = 0;
  for (std::size_t i = 0; i < h.size(); ++i) {
    const double dx = std::pow(h[i], p) - mx;
    sxy += dx * (f[i] - my);
    sxx += dx * dx;
  }
  a = sxx > 0 ? sxy / sxx : 0;
  f0 = my - a * mx;
  double ss = 0;
  for (std::size_t i = 0; i < h.size(); ++i) ss += std::pow(f0 + a * std::pow(h[i], p) - f[i], 2);
  return ss;
}

/// The least-squares part of `g` (four or more levels; h scaled by the finest spacing).
void leastSquares(const std::vector<double>& h_in, const std::vector<double>& f, double formal_order, double fine_h, GridConvergence& g) {
  std::vector<double> h;
  for (const double v : h_in) h.push_back(v / fine_h);  // finest at 1: h^p stays moderate for p up to 8
  // A scan of p on a 0.01 grid, then golden-section refinement around the best node.
  double best_p = 0.01, best = std::numeric_limits<double>::infinity(), f0 = 0, a = 0;
  for (int k = 1; k <= 800; ++k) {
    const double p = 0.01 * k, ss = fitAt(h, f, p, f0, a);
    if (ss < best) {
      best = ss;
      best_p = p;
    }
  }
  double lo = std::max(1e-3, best_p - 0.01), hi = std::min(8.0, best_p + 0.01);
  const double gr = 0.5 * (std::sqrt(5.0) - 1);
  for (int k = 0; k < 60; ++k) {
    const double c = hi - gr * (hi - lo), d = lo + gr * (hi - lo);
    if (fitAt(h, f, c, f0, a) < fitAt(h, f, d, f0, a)) hi = d;
    else lo = c;
  }
  const double p = 0.5 * (lo + hi);
  const double ss = fitAt(h, f, p, f0, a);
  const double n = static_cast<double>(h.size());
  g.has_fit = true;
  g.fit_levels = static_cast<int>(h.size());
  g.fit_order = p;
  g.fit_extrapolated = f0;
  g.fit_scatter = std::sqrt(ss / (n - 3));
  const double fine = g.fine;
  const bool credible = p >= 0.5 && p <= 2.1;
  double u0 = f0, ua = a;
  if (!credible) fitAt(h, f, formal_order, u0, ua);
  g.fit_order_used = credible ? p : formal_order;
  const double u = (credible ? 1.25 : 3.0) * std::abs(fine - u0) + g.fit_scatter + std::abs(fine - (u0 + ua));
  g.fit_uncertainty = fine != 0 ? u / std::abs(fine) : GridConvergence::nan;
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
    g.note += fmt::format("; least squares over all {} levels (Eca & Hoekstra 2014): order {:.2f}, extrapolated {:.6g}, scatter {:.3g}",
                          g.fit_levels, g.fit_order, g.fit_extrapolated, g.fit_scatter);
  }
  if (std::isfinite(g.gci)) {
    g.band_lo = g.fine - g.gci * std::abs(g.fine);
    g.band_hi = g.fine + g.gci * std::abs(g.fine);
  }
  return g;
}

}  // namespace mmval::simulate
