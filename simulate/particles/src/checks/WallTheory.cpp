#include "WallTheory.hpp"

#include <numeric>
#include <sstream>

#include <fmt/format.h>
#include <gsl/gsl_cdf.h>

#include "mmval/particles/Physics.hpp"

namespace mmval::particles::checks {

double ksPValue(double d, double n) {
  const double sn = std::sqrt(n), t = (sn + 0.12 + 0.11 / sn) * d;
  if (t < 0.2) return 1.0;
  double q = 0.0;
  for (int k = 1; k <= 200; ++k) {
    const double term = std::exp(-2.0 * k * k * t * t);
    q += (k % 2 ? 2.0 : -2.0) * term;
    if (term < 1e-16) break;
  }
  return std::clamp(q, 0.0, 1.0);
}

SedimentationStats sedimentationStats(const std::vector<std::vector<double>>& z, const Barometric& ref, int bins) {
  SedimentationStats st;
  const std::size_t m = z.size(), n = z.front().size();
  // Mean height: particles are independent, so the spread of their time averages gives its standard error.
  std::vector<double> per(n, 0.0);
  for (const auto& snap : z)
    for (std::size_t i = 0; i < n; ++i) per[i] += snap[i] / static_cast<double>(m);
  double s = 0, s2 = 0;
  for (double v : per) s += v;
  st.mean = s / static_cast<double>(n);
  for (double v : per) s2 += (v - st.mean) * (v - st.mean);
  st.se = std::sqrt(s2 / static_cast<double>(n - 1) / static_cast<double>(n));
  // Lag-1 correlation of a particle's height between consecutive snapshots (0: independent samples).
  std::vector<double> all;
  for (const auto& snap : z) all.insert(all.end(), snap.begin(), snap.end());
  const double N = static_cast<double>(all.size());
  st.samples = static_cast<std::int64_t>(all.size());
  const double mu = std::accumulate(all.begin(), all.end(), 0.0) / N;
  double c01 = 0, c00 = 0;
  for (std::size_t k = 0; k + 1 < m; ++k)
    for (std::size_t i = 0; i < n; ++i) c01 += (z[k][i] - mu) * (z[k + 1][i] - mu);
  for (double v : all) c00 += (v - mu) * (v - mu);
  st.lag1 = m > 1 ? c01 / static_cast<double>((m - 1) * n) / (c00 / N) : 0.0;
  // Correlated snapshots carry fewer independent samples: n_eff = N (1 - r) / (1 + r) for an
  // AR(1) series of lag-1 correlation r (e.g. Zwiers & von Storch 1995, J. Climate 8:336).
  const double r = std::clamp(st.lag1, 0.0, 0.99);
  st.n_eff = N * (1 - r) / (1 + r);
  // Pooled samples: KS distance to the reference CDF, chi-square over equiprobable bins, both
  // judged with n_eff (the chi-square scaled by n_eff / N).
  std::sort(all.begin(), all.end());
  for (std::size_t k = 0; k < all.size(); ++k) {
    const double f = ref.cdf(all[k]);
    st.ks_d = std::max({st.ks_d, (k + 1) / N - f, f - k / N});
  }
  st.ks_p = ksPValue(st.ks_d, st.n_eff);
  std::vector<double> equi(static_cast<std::size_t>(bins), 0.0);
  for (double v : all) equi[std::min<std::size_t>(static_cast<std::size_t>(ref.cdf(v) * bins), bins - 1)] += 1;
  const double expect = N / bins;
  for (double o : equi) st.chi2 += (o - expect) * (o - expect) / expect;
  st.chi2 *= st.n_eff / N;
  st.chi2_p = gsl_cdf_chisq_Q(st.chi2, bins - 1);
  // Equal-width histogram for plotting: measured and expected densities.
  std::ostringstream csv;
  csv << "z_um,gap_um,count,density_1_per_um,boltzmann_density_1_per_um,expected_count\n";
  const double w = ref.span / bins;
  std::vector<double> hist(static_cast<std::size_t>(bins), 0.0);
  for (double v : all) hist[std::clamp<std::size_t>(static_cast<std::size_t>((v - ref.a) / w), 0, bins - 1)] += 1;
  for (int b = 0; b < bins; ++b) {
    const double z0 = ref.a + b * w, zc = z0 + 0.5 * w, p = ref.cdf(z0 + w) - ref.cdf(z0);
    csv << fmt::format("{:.6g},{:.6g},{},{:.6g},{:.6g},{:.6g}\n", zc * 1e6, (zc - ref.a) * 1e6, hist[b], hist[b] / N / (w * 1e6),
                       p / (w * 1e6), p * N);
  }
  st.histogram_csv = csv.str();
  return st;
}

double meanHeightWithoutItoDrift(const Barometric& ref, double h) {
  const double a = ref.a, g_floor = 1e-3 * a;
  const auto weight = [&](double z) { return twoWallPerpendicular(a, std::clamp(z, a + g_floor, h - a - g_floor), h) * std::exp(-(z - a) / ref.ls); };
  // Symmetric in the two plates' gaps: integrate gap g from the bottom up to the mid-plane and from the top down.
  const int n = 400;
  double w0 = 0, w1 = 0;
  const double half = 0.5 * ref.span, lo = std::log(g_floor), hi = std::log(half), du = (hi - lo) / n;
  for (int side = 0; side < 2; ++side)
    for (int k = 0; k <= n; ++k) {
      const double g = std::exp(lo + k * du), z = side == 0 ? a + g : h - a - g;
      const double simpson = (k == 0 || k == n) ? 1.0 : (k % 2 ? 4.0 : 2.0);
      const double f = weight(z) * g * du / 3.0 * simpson;  // dz = g du
      w0 += f;
      w1 += f * z;
    }
  // The slivers below the floor, where the factor is held constant.
  for (double z : {a + 0.5 * g_floor, h - a - 0.5 * g_floor}) {
    w0 += weight(z) * g_floor;
    w1 += weight(z) * g_floor * z;
  }
  return w1 / w0;
}

}  // namespace mmval::particles::checks
