#include "SlitTheory.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace mmval::particles::checks {

namespace {

/// One level of adaptive Simpson (Lyness 1969): Richardson's correction once |diff| <= 15 eps.
double simpsonStep(const std::function<double(double)>& f, double lo, double hi, double f_lo, double f_mid, double f_hi, double whole,
                   double eps, int depth) {
  const double mid = 0.5 * (lo + hi), l_mid = 0.5 * (lo + mid), r_mid = 0.5 * (mid + hi);
  const double f_l = f(l_mid), f_r = f(r_mid);
  const double left = (mid - lo) / 6 * (f_lo + 4 * f_l + f_mid), right = (hi - mid) / 6 * (f_mid + 4 * f_r + f_hi);
  const double diff = left + right - whole;
  if (depth >= 50 || std::abs(diff) <= 15 * eps) return left + right + diff / 15;
  return simpsonStep(f, lo, mid, f_lo, f_l, f_mid, left, 0.5 * eps, depth + 1) +
         simpsonStep(f, mid, hi, f_mid, f_r, f_hi, right, 0.5 * eps, depth + 1);
}

}  // namespace

double integrate(const std::function<double(double)>& f, double lo, double hi, double eps) {
  if (!(hi > lo)) return 0.0;
  const double f_lo = f(lo), f_hi = f(hi), f_mid = f(0.5 * (lo + hi));
  return simpsonStep(f, lo, hi, f_lo, f_mid, f_hi, (hi - lo) / 6 * (f_lo + 4 * f_mid + f_hi), eps, 0);
}

double bisect(const std::function<double(double)>& g, double lo, double hi, double tol) {
  for (int it = 0; it < 200 && hi - lo > tol; ++it) {
    const double mid = 0.5 * (lo + hi);
    (g(mid) > 0 ? hi : lo) = mid;
  }
  return 0.5 * (lo + hi);
}

EntryFlux::EntryFlux(const DriftAt& drift, double a, double h) : m_a(a), m_dz((h - 2 * a) / kCells), m_w(kCells + 1, 0.0) {
  double prev = drift(a).x();
  for (int j = 1; j <= kCells; ++j) {
    const double v = drift(a + j * m_dz).x();
    m_w[j] = m_w[j - 1] + 0.5 * (prev + v) * m_dz;
    prev = v;
  }
}

double EntryFlux::fractionBelow(double z) const {
  const double f = std::clamp((z - m_a) / m_dz, 0.0, static_cast<double>(kCells));
  const int j = std::min(static_cast<int>(f), kCells - 1);
  return (m_w[j] + (f - j) * (m_w[j + 1] - m_w[j])) / total();
}

double EntryFlux::quantile(double q) const {
  const double target = q * total();
  const auto it = std::upper_bound(m_w.begin(), m_w.end(), target);
  const int j = std::clamp(static_cast<int>(it - m_w.begin()) - 1, 0, kCells - 1);
  const double dw = m_w[j + 1] - m_w[j];
  return m_a + (j + (dw > 0 ? (target - m_w[j]) / dw : 0.0)) * m_dz;
}

double cubicF(double s) { return 3 * s * s - 2 * s * s * s; }

double pointFraction(double L, double h, double U, double vs, double a, double c) {
  const double sa = a / h, st = 1 - sa, sc = (a + c) / h;
  const double target = cubicF(sc) + L * vs / (U * h);
  if (target >= cubicF(st)) return 1.0;
  const double s_star = bisect([&](double s) { return cubicF(s) - target; }, sc, st, 1e-15);
  return (cubicF(s_star) - cubicF(sa)) / (cubicF(st) - cubicF(sa));
}

double trajectoryDistance(const DriftAt& drift, double z0, double a, double c, double scale) {
  if (z0 - a <= c) return 0.0;
  const auto integrand = [&](double w) {
    const double gap = std::exp(w);
    const Vec3 v = drift(a + gap);
    return v.x() / std::abs(v.z()) * gap;
  };
  return integrate(integrand, std::log(c), std::log(z0 - a), 1e-9 * scale);
}

double trajectoryFraction(const DriftAt& drift, const EntryFlux& flux, double L, double a, double c, double h, double scale) {
  const double z_top = h - a;
  if (trajectoryDistance(drift, z_top, a, c, scale) <= L) return 1.0;
  const double z_star = bisect([&](double z) { return trajectoryDistance(drift, z, a, c, scale) - L; }, a + c, z_top, 1e-9 * h);
  return flux.fractionBelow(z_star);
}

namespace {

/// phi(eta_c) and the two weighted integrals for a trial lambda (RK4, `steps` steps on [0, eta_c]).
struct Shot {
  double phi1 = 0, first = 0, second = 0;
};

Shot shoot(double lambda, int steps, double eta_c) {
  // y = (phi, phi', int (1 - eta^2) phi, int (1 - eta^2) phi^2)
  using State = std::array<double, 4>;
  const double l2 = lambda * lambda;
  const auto rhs = [&](double eta, const State& y) {
    const double w = 1 - eta * eta;
    return State{y[1], -l2 * w * y[0], w * y[0], w * y[0] * y[0]};
  };
  State y{1.0, 0.0, 0.0, 0.0};
  const double dx = eta_c / steps;
  for (int i = 0; i < steps; ++i) {
    const double x = i * dx;
    const State k1 = rhs(x, y);
    State t;
    for (int j = 0; j < 4; ++j) t[j] = y[j] + 0.5 * dx * k1[j];
    const State k2 = rhs(x + 0.5 * dx, t);
    for (int j = 0; j < 4; ++j) t[j] = y[j] + 0.5 * dx * k2[j];
    const State k3 = rhs(x + 0.5 * dx, t);
    for (int j = 0; j < 4; ++j) t[j] = y[j] + dx * k3[j];
    const State k4 = rhs(x + dx, t);
    for (int j = 0; j < 4; ++j) y[j] += dx / 6 * (k1[j] + 2 * k2[j] + 2 * k3[j] + k4[j]);
  }
  return {y[0], y[2], y[3]};
}

}  // namespace

GraetzSeries graetzSeries(int modes, double eta_c, double eta_a) {
  constexpr int kSteps = 8000;  // >= 40 steps per wavelength up to lambda ~ 170 (40 modes)
  GraetzSeries g;
  double lo = 0.5, f_lo = shoot(lo, kSteps, eta_c).phi1;
  while (static_cast<int>(g.lambda.size()) < modes) {
    const double hi = lo + 0.05, f_hi = shoot(hi, kSteps, eta_c).phi1;
    if ((f_lo > 0) != (f_hi > 0)) {
      double a = lo, b = hi, fa = f_lo;
      for (int it = 0; it < 60; ++it) {
        const double m = 0.5 * (a + b), fm = shoot(m, kSteps, eta_c).phi1;
        if ((fm > 0) == (fa > 0)) {
          a = m;
          fa = fm;
        } else {
          b = m;
        }
      }
      const double lambda = 0.5 * (a + b);
      const Shot s = shoot(lambda, kSteps, eta_c);
      g.lambda.push_back(lambda);
      g.weight.push_back(s.first * s.first / (s.second * (eta_c - eta_c * eta_c * eta_c / 3)));
    }
    lo = hi;
    f_lo = f_hi;
  }
  g.entry_fraction = (eta_c - eta_c * eta_c * eta_c / 3) / (eta_a - eta_a * eta_a * eta_a / 3);
  return g;
}

double levequePenetration(double mu_prime) { return 1.0 - 3.0 * std::cbrt(2.0 / 3.0) / std::tgamma(4.0 / 3.0) * std::pow(mu_prime, 2.0 / 3.0); }

}  // namespace mmval::particles::checks
