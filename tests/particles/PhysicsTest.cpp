// Single-particle formulas against the values of reference-data/particle-facts.toml
// (Stokes, Einstein, Faxen, Brenner, Hertz as given by Johnson; sources there).
// Tolerances: the references are printed to 2-4 significant digits, so each
// check allows half a unit of the last printed digit (stated per check).
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "mmval/core/DataPaths.hpp"
#include "mmval/core/ReferenceData.hpp"
#include "mmval/particles/Physics.hpp"

namespace mmval::particles {
namespace {

ParticleMaterial polystyrene(double d) {
  ParticleMaterial p;
  p.diameter = d;
  p.density = 1050;
  return p;
}

TEST(Physics, RelaxationTimesMatchBenchmarks) {
  const Fluid water;
  EXPECT_NEAR(relaxationTime(water, polystyrene(5e-6)), 1.5e-6, 0.05e-6);
  EXPECT_NEAR(relaxationTime(water, polystyrene(10e-6)), 5.8e-6, 0.05e-6);
  EXPECT_NEAR(relaxationTime(water, polystyrene(15e-6)), 1.3e-5, 0.05e-5);
}

TEST(Physics, StokesSettlingAndTimeThrough20umMatchBenchmarks) {
  const Fluid water;  // 998.2 kg/m3: the density the reference values imply
  EXPECT_NEAR(settlingSpeed(water, polystyrene(5e-6)), 7.1e-7, 0.05e-7);
  EXPECT_NEAR(settlingSpeed(water, polystyrene(10e-6)), 2.8e-6, 0.05e-6);
  EXPECT_NEAR(settlingSpeed(water, polystyrene(15e-6)), 6.4e-6, 0.05e-6);
  EXPECT_NEAR(20e-6 / settlingSpeed(water, polystyrene(5e-6)), 28.0, 0.5);
  EXPECT_NEAR(20e-6 / settlingSpeed(water, polystyrene(10e-6)), 7.1, 0.05);
  EXPECT_NEAR(20e-6 / settlingSpeed(water, polystyrene(15e-6)), 3.1, 0.05);
}

TEST(Physics, StokesEinsteinAt293K) {
  Fluid water;
  water.temperature = 293.0;
  EXPECT_NEAR(stokesEinstein(water, 5e-6), 8.6e-14, 0.05e-14);
  EXPECT_NEAR(stokesEinstein(water, 10e-6), 4.3e-14, 0.05e-14);
}

TEST(Physics, FaxenParallelMatchesTabulatedValues) {
  // x = a/h: 1.060 at 0.1, 1.126 at 0.2, 1.386 at 0.5. The series gives 1.05948 at
  // 0.1 (the reference rounds it up), so one unit of the last digit there.
  EXPECT_NEAR(faxenParallel(0.1, 1.0), 1.060, 1e-3);
  EXPECT_NEAR(faxenParallel(0.2, 1.0), 1.126, 5e-4);
  EXPECT_NEAR(faxenParallel(0.5, 1.0), 1.386, 5e-4);
}

TEST(Physics, BrennerPerpendicularMatchesTabulatedValues) {
  // h/a: 11.46 at 1.1, 2.126 at 2, 1.126 at 10 (half a unit of the last digit)
  EXPECT_NEAR(brennerPerpendicular(1.0, 1.1), 11.46, 5e-3);
  EXPECT_NEAR(brennerPerpendicular(1.0, 2.0), 2.126, 5e-4);
  EXPECT_NEAR(brennerPerpendicular(1.0, 10.0), 1.126, 5e-4);
  // Far field: method of reflections 1 / (1 - 9/8 a/h) + O((a/h)^3)
  EXPECT_NEAR(brennerPerpendicular(1.0, 1000.0), 1.0 / (1.0 - 9.0 / 8000.0), 1e-8);
}

// Goldman, Cox & Brenner's (1967) exact tables (reference-data/goldman-cox-brenner.toml).
const ReferenceFile& gcb() { return loadReferenceFile(referenceDataDirectory() / "goldman-cox-brenner.toml"); }
double gcbRow(const std::string& quantity, double h_over_a) {
  const auto rows = gcb().find(quantity, AtMap{{"h_over_a", h_over_a}});
  EXPECT_EQ(rows.size(), 1u) << quantity << " at " << h_over_a;
  return rows.empty() ? 0.0 : *rows.front()->value;
}
constexpr double kGcbHeights[] = {10.0677, 3.7622, 2.3524, 1.5431, 1.1276, 1.0453, 1.005004, 1.003202};

// The parallel drag of a sphere free to rotate against the table (torque-free value
// derived from GCB I's resistances): the join of lubrication and Faxen is within 1.1 %
// (at h/a = 1.1276), so 1.2 %; Faxen alone is 23 % low near contact.
TEST(Physics, FreeSphereParallelDragMatchesGoldmanCoxBrenner) {
  for (const double s : kGcbHeights) {
    const double ref = gcbRow("lambda_free", s);
    EXPECT_NEAR(freeSphereParallel(1.0, s), ref, 0.012 * ref) << "h/a = " << s;
  }
  EXPECT_LT(faxenParallel(1.0, 1.003202), 0.8 * gcbRow("lambda_free", 1.003202));
  // Beyond a gap of one radius it is Faxen's series exactly; below 0.01 a the lubrication
  // forms exactly: GCB I's F_t, T_t, T_r at delta/a = 1e-3, combined by hand.
  EXPECT_DOUBLE_EQ(freeSphereParallel(1.0, 2.0), faxenParallel(1.0, 2.0));
  EXPECT_DOUBLE_EQ(freeSphereParallel(1.0, 5.0), faxenParallel(1.0, 5.0));
  const double L = std::log(1e3);
  const double f_t = 8.0 / 15.0 * L + 0.9588, t_t = L / 10.0 - 0.1895, t_r = 0.4 * L + 0.3817;
  EXPECT_NEAR(freeSphereParallel(1.0, 1.001), f_t - 4.0 / 3.0 * t_t * t_t / t_r, 1e-12);
  EXPECT_THROW(freeSphereParallel(1.0, 1.0), std::invalid_argument);
}

// Smooth, monotone join: on 4000 log-spaced gaps from 1e-4 a to 100 a the drag factor falls
// strictly, and neighbouring samples (0.15 % apart in gap) differ by < 0.5 % (no kink or step).
TEST(Physics, ParallelDragJoinIsMonotoneAndSmooth) {
  double prev = freeSphereParallel(1.0, 1.0 + 1e-4);
  for (int k = 1; k <= 4000; ++k) {
    const double gap = std::pow(10.0, -4.0 + 6.0 * k / 4000.0), lam = freeSphereParallel(1.0, 1.0 + gap);
    ASSERT_LT(lam, prev) << "gap/a = " << gap;
    ASSERT_LT((prev - lam) / lam, 5e-3) << "gap/a = " << gap;
    prev = lam;
  }
  EXPECT_DOUBLE_EQ(nearContactWeight(1.0, 1.005), 1.0);
  EXPECT_DOUBLE_EQ(nearContactWeight(1.0, 2.5), 0.0);
  EXPECT_NEAR(nearContactWeight(1.0, 1.1), 0.5, 1e-12);  // ln-midpoint of [0.01, 1]
}

// Free sphere in shear against the table (values derived from GCB's resistances by the
// force and torque balance): velocity within 1.0 %, rotation within 2.5 %, so 1.2 % and 3 %.
TEST(Physics, FreeSphereInShearMatchesGoldmanCoxBrenner) {
  for (const double s : kGcbHeights) {
    const auto r = freeSphereInShear(1.0, s);
    const double u = gcbRow("U_over_gamma_h", s), om = gcbRow("Omega_over_gamma", s);
    EXPECT_NEAR(r.velocity, u, 0.012 * u) << "h/a = " << s;
    EXPECT_NEAR(r.rotation, om, 0.03 * om) << "h/a = " << s;
  }
  // Far away: Faxen / GCB II's method of reflections exactly.
  EXPECT_DOUBLE_EQ(freeSphereInShear(1.0, 4.0).velocity, 1.0 - 5.0 / 16.0 / 64.0);
  EXPECT_DOUBLE_EQ(freeSphereInShear(1.0, 4.0).rotation, 0.5 * (1.0 - 5.0 / 16.0 / 64.0));
  EXPECT_THROW(freeSphereInShear(1.0, 0.9), std::invalid_argument);
}

// Near contact the model tends to GCB II's leading-order asymptote U/(gamma a) ~
// 0.7431 / (0.6376 - 0.2 ln(delta/a)); the terms it keeps beyond that order shrink
// like 1/ln(a/delta): 9 % away at delta/a = 1e-3, < 3 % at 1e-12.
TEST(Physics, FreeSphereInShearTendsToGcbAsymptote) {
  const auto ratio = [](double gap) {
    return freeSphereInShear(1.0, 1.0 + gap).velocity * (1.0 + gap) / (0.7431 / (0.6376 - 0.2 * std::log(gap)));
  };
  EXPECT_GT(ratio(1e-3), ratio(1e-6));
  EXPECT_GT(ratio(1e-6), ratio(1e-12));
  EXPECT_NEAR(ratio(1e-12), 1.0, 0.03);
  EXPECT_NEAR(ratio(1e-3), 1.0, 0.1);
}

// A sphere further from the wall moves faster (U = gamma z f rises with z) and turns faster.
TEST(Physics, FreeSphereInShearIsMonotoneInHeight) {
  double u_prev = 0, om_prev = 0;
  for (int k = 0; k <= 4000; ++k) {
    const double z = 1.0 + std::pow(10.0, -4.0 + 6.0 * k / 4000.0);
    const auto r = freeSphereInShear(1.0, z);
    ASSERT_GT(r.velocity * z, u_prev) << "z/a = " << z;
    ASSERT_GT(r.rotation, om_prev) << "z/a = " << z;
    u_prev = r.velocity * z;
    om_prev = r.rotation;
  }
}

// The slit's lag is symmetric about the mid-plane; its depth average (Gauss-Legendre on
// graded panels) agrees with a 2e5-point midpoint rule to 1e-5 u_mean; without the lag the
// closed form (6 s (1 - s) averaged over [a/h, 1 - a/h], minus Faxen's 2 a^2/h^2).
TEST(Physics, SlitLagIsSymmetricAndItsDepthAverageConverges) {
  const double a = 2.5e-6, h = 20e-6;
  EXPECT_NEAR(slitShearLag(a, 4e-6, h), slitShearLag(a, h - 4e-6, h), 1e-15);
  EXPECT_LT(slitShearLag(a, 1.01 * a, h), slitShearLag(a, 0.5 * h, h));
  const int n = 200000;
  double sum = 0;
  for (int i = 0; i < n; ++i) sum += slitShearLag(a, a + (i + 0.5) * (h - 2 * a) / n, h);
  const double s0 = a / h, s1 = 1 - s0;
  const double plain = (3 * (s1 * s1 - s0 * s0) - 2 * (s1 * s1 * s1 - s0 * s0 * s0)) / (s1 - s0);
  EXPECT_NEAR(slitMeanParticleSpeed(a, h, false, false), plain, 1e-12);
  EXPECT_NEAR(slitMeanParticleSpeed(a, h, true, false), plain - 2 * s0 * s0, 1e-12);
  EXPECT_NEAR(slitMeanParticleSpeed(a, h, true, true), plain - 2 * s0 * s0 + sum / n, 1e-5);
  EXPECT_THROW(slitMeanParticleSpeed(a, 2 * a, true, true), std::invalid_argument);
}

TEST(Physics, HertzContactTimeFormulaAndRayleighStep) {
  ParticleMaterial p = polystyrene(5e-6);
  p.youngs_modulus = 1e6;
  p.poisson_ratio = 0.3;
  // t_c = 2.868 (m*^2 / (R* E*^2 v))^(1/5) by hand for equal spheres at 0.05 m/s
  const double m = p.mass() / 2, r = p.radius() / 2, e = 1e6 / (2 * (1 - 0.09)), v = 0.05;
  const double tc = 2.868 * std::pow(m * m / (r * e * e * v), 0.2);
  EXPECT_NEAR(hertzContactTimeEqual(p, v), tc, 1e-12 * tc);
  // t_c ~ v^(-1/5)
  EXPECT_NEAR(hertzContactTimeEqual(p, 32 * v), tc / 2, 1e-12 * tc);
  // 10 % of the Rayleigh time (the usual DEM step bound) is 4.4e-8 s at E = 1e6 Pa, 4.4e-9 s at 1e8 Pa
  EXPECT_NEAR(0.1 * rayleighTime(p), 4.4e-8, 0.05e-8);
  p.youngs_modulus = 1e8;
  EXPECT_NEAR(0.1 * rayleighTime(p), 4.4e-9, 0.05e-9);
  EXPECT_THROW(hertzContactTime(1, 1, 1, 0), std::invalid_argument);
}

}  // namespace
}  // namespace mmval::particles
