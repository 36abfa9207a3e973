// The theory the wall checks (WallChecks.cpp) are judged against, apart from
// their scenes: Boltzmann's height distribution between two plates and the
// statistics that compare sampled heights with it, the stationary mean height
// of the Ito Fokker-Planck equation without its drift term, and the variance
// estimator of displacements. Internal to mmval::particles (tests include it).
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace mmval::particles::checks {

/// The truncated exponential (Boltzmann) distribution of centre heights on [a, h - a].
struct Barometric {
  double a, span, ls;  ///< radius, accessible span h - 2a, sedimentation length (m)
  double norm() const { return -std::expm1(-span / ls); }
  double cdf(double z) const { return std::clamp(-std::expm1(-(z - a) / ls) / norm(), 0.0, 1.0); }
  double quantile(double u) const { return a - ls * std::log1p(-u * norm()); }
  /// <z> = a + l_s - L e^{-L/l_s} / (1 - e^{-L/l_s}), L = h - 2a.
  double mean() const { return a + ls - span * std::exp(-span / ls) / norm(); }
};

/// Kolmogorov's limiting distribution Q(t) = 2 sum (-1)^(k-1) exp(-2 k^2 t^2), with
/// Stephens' (1970, J. R. Stat. Soc. B 32:115) finite-n argument t = (sqrt n + 0.12 + 0.11 / sqrt n) D.
double ksPValue(double d, double n);

struct SedimentationStats {
  double mean = 0, se = 0, ks_d = 0, ks_p = 0, chi2 = 0, chi2_p = 0, lag1 = 0, n_eff = 0;
  std::int64_t samples = 0;
  std::string histogram_csv;
};

/// z[snapshot][particle] against the Boltzmann distribution `ref`.
SedimentationStats sedimentationStats(const std::vector<std::vector<double>>& z, const Barometric& ref, int bins);

/// Mean height the engine would reach WITHOUT the Ito drift k_B T dM/dz: the Ito
/// Fokker-Planck equation then has zero flux for p ~ lambda_perp(z) exp(-(z - a) / l_s)
/// (p D = const exp(-z / l_s)), which piles particles up at the plates. Quadrature in
/// log(gap) with the two-plate Brenner factor floored at gap = 1e-3 a like the engine's.
double meanHeightWithoutItoDrift(const Barometric& ref, double h);

/// Sample variance and its standard error sqrt((m4 - s^4) / n) for each component.
struct Moments {
  double s1 = 0, s2 = 0, s3 = 0, s4 = 0, n = 0;
  void add(double v) { s1 += v; s2 += v * v; s3 += v * v * v; s4 += v * v * v * v; n += 1; }
  double mean() const { return s1 / n; }
  double var() const { const double m = mean(); return s2 / n - m * m; }
  double varSe() const {
    const double m = mean(), m4 = s4 / n - 4 * m * s3 / n + 6 * m * m * s2 / n - 3 * m * m * m * m, v = var();
    return std::sqrt(std::max(m4 - v * v, 0.0) / n);
  }
};

}  // namespace mmval::particles::checks
