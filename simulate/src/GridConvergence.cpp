#include "mmval/simulate/GridConvergence.hpp"

#include <algorithm>
#include <cmath>
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
  if (std::isfinite(g.gci)) {
    g.band_lo = g.fine - g.gci * std::abs(g.fine);
    g.band_hi = g.fine + g.gci * std::abs(g.fine);
  }
  return g;
}

}  // namespace mmval::simulate
