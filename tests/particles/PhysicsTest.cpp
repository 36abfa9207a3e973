// Single-particle formulas against benchmarks.md ("Particles in a viscous fluid").
// Tolerances: the references are printed to 2-4 significant digits, so each
// check allows half a unit of the last printed digit (stated per check).
#include <gtest/gtest.h>

#include <cmath>

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
  const Fluid water;  // 998.2 kg/m3: the density benchmarks.md's numbers imply
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
  // 0.1 (benchmarks.md rounds it up), so one unit of the last digit there.
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
  // liggghts-notes.md: 10 % of the Rayleigh time is 4.4e-8 s at E = 1e6 Pa, 4.4e-9 s at 1e8 Pa
  EXPECT_NEAR(0.1 * rayleighTime(p), 4.4e-8, 0.05e-8);
  p.youngs_modulus = 1e8;
  EXPECT_NEAR(0.1 * rayleighTime(p), 4.4e-9, 0.05e-9);
  EXPECT_THROW(hertzContactTime(1, 1, 1, 0), std::invalid_argument);
}

}  // namespace
}  // namespace mmval::particles
