// Checks 1, 2 and 8 of docs/validation/particle-physics.md (WallChecks.cpp): the shipped cases run and meet
// their acceptance entries, and the measured values agree with the literature
// numbers of reference-data/wall-hydrodynamics.toml and rsa-blocking.toml within
// 3 of their own standard errors (seeds fixed in the cases). The theory functions
// themselves (WallTheory.hpp) are tested directly against closed forms and quadrature.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <random>
#include <sstream>
#include <string>

#include <fmt/format.h>

#include "ParticleRegistry.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/ReferenceData.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/particles/Physics.hpp"

#include "../../simulate/particles/src/checks/WallTheory.hpp"

namespace mmval::particles {
namespace {

namespace fs = std::filesystem;
using test_support::particleRegistry;

const fs::path kCases = fs::path(MMVAL_SOURCE_DIR) / "cases";
const fs::path kReference = fs::path(MMVAL_SOURCE_DIR) / "reference-data" / "wall-hydrodynamics.toml";

fs::path outDir(const std::string& name) { return fs::path(MMVAL_BINARY_DIR) / "tests" / "particles" / name; }

/// A metric of the run in its display unit; fails the test when absent.
double metric(const RunSummary& s, const std::string& name) {
  // Metrics with labelled acceptance entries are named "name (label)"; all carry the same value.
  for (const auto& m : s.metrics)
    if (m.name == name || m.name.starts_with(name + " (")) return m.value;
  ADD_FAILURE() << "no metric " << name;
  return std::nan("");
}

double referenceValue(const std::string& quantity, const AtMap& at) {
  const auto rows = loadReferenceFile(kReference).find(quantity, at);
  EXPECT_EQ(rows.size(), 1u) << quantity << " " << toString(at);
  return rows.empty() ? std::nan("") : *rows.front()->value;
}

RunSummary runShipped(const std::string& file, const std::string& out, const std::vector<CaseOverride>& overrides = {}) {
  const Case c = Case::load(kCases / file, particleRegistry(), overrides);
  RunSummary s = runCase(c, particleRegistry(), outDir(out), {.quiet = true});
  for (const auto& m : s.metrics)
    std::cout << m.name << " = " << m.value << " " << m.unit << (m.pass ? (*m.pass ? "  PASS" : "  FAIL") : "") << "\n";
  return s;
}

// Check 1. The reference row is Boltzmann's mean height for the case's particle and gap.
TEST(WallChecks, SedimentationEquilibriumIsBoltzmann) {
  const RunSummary s = runShipped("physics-sedimentation-equilibrium.toml", "physics-sedimentation-run");
  EXPECT_TRUE(s.all_pass);
  EXPECT_TRUE(fs::exists(outDir("physics-sedimentation-run") / "height_histogram.csv"));
  const double ref = referenceValue("mean_height", {{"d_um", 1.0}, {"rho_p_kg_m3", 2000.0}, {"rho_f_kg_m3", 998.2}, {"gap_um", 5.0}, {"T_K", 293.15}});
  // The runner's own analytic mean must be the tabulated one (round-off of the 6 digits stored).
  EXPECT_NEAR(metric(s, "mean_height_reference"), ref, 1e-5);
  const double mean = metric(s, "mean_height"), se = metric(s, "mean_height_se");
  EXPECT_GT(se, 0.0);
  EXPECT_LE(std::abs(mean - ref), 3 * se) << fmt::format("mean height {} um, Boltzmann {} um, SE {} um", mean, ref, se);
  // The check has power: without the Ito drift the mean would sit > 10 standard errors low.
  EXPECT_LT(metric(s, "without_ito_zscore"), -10.0);
  // Snapshots 5 s apart are only weakly correlated (the case's n_eff assumes r ~ 0.25).
  EXPECT_LT(metric(s, "snapshot_correlation"), 0.4);
}

// Check 1, constant mobility: Boltzmann holds whatever the mobility (and no drift term is involved).
TEST(WallChecks, SedimentationWithoutHindranceIsBoltzmannToo) {
  const RunSummary s = runShipped("physics-sedimentation-equilibrium.toml", "physics-sedimentation-free-run",
                                  {{"physics.wall_hindrance", "false"}, {"particles.count", "100"}, {"run.duration", "80 s"}});
  const double mean = metric(s, "mean_height"), ref = metric(s, "mean_height_reference"), se = metric(s, "mean_height_se");
  EXPECT_LE(std::abs(mean - ref), 3 * se) << fmt::format("mean height {} um, Boltzmann {} um, SE {} um", mean, ref, se);
  EXPECT_DOUBLE_EQ(metric(s, "mean_height_without_ito"), ref);
}

// Check 1 can fail: with the engine's Ito drift switched off, particles settle to the
// Fokker-Planck prediction without the drift (mean_height_without_ito), not to Boltzmann.
TEST(WallChecks, SedimentationWithoutItoDriftFailsTheCheck) {
  const RunSummary s = runShipped("physics-sedimentation-equilibrium.toml", "physics-sedimentation-no-ito-run",
                                  {{"physics.ito_drift", "false"}, {"particles.count", "100"}, {"run.duration", "80 s"}});
  EXPECT_FALSE(s.all_pass);
  const double mean = metric(s, "mean_height"), no_ito = metric(s, "mean_height_without_ito"), se = metric(s, "mean_height_se");
  EXPECT_LE(std::abs(mean - no_ito), 4 * se) << fmt::format("mean height {} um, without-drift prediction {} um, SE {} um", mean, no_ito, se);
  EXPECT_GT(std::abs(mean - metric(s, "mean_height_reference")), 10 * se);
}

// Check 2: normal factor against Brenner at every height, parallel against Faxen where the series holds.
TEST(WallChecks, HinderedDiffusionMatchesBrennerAndFaxen) {
  const RunSummary s = runShipped("physics-hindered-diffusion.toml", "physics-hindered-diffusion-run");
  EXPECT_TRUE(s.all_pass);
  EXPECT_TRUE(fs::exists(outDir("physics-hindered-diffusion-run") / "hindered_diffusion.csv"));
  const std::vector<std::pair<double, std::string>> heights = {
      {1.1276, "1.128"}, {1.5431, "1.543"}, {2.3524, "2.352"}, {3.7622, "3.762"}, {10.0677, "10.07"}};
  for (const auto& [z, label] : heights) {
    const double ref = referenceValue("lambda_perp", {{"z_over_a", z}});
    const double got = metric(s, "lambda_perp_" + label), se = metric(s, "lambda_perp_se_" + label);
    EXPECT_GT(se, 0.0);
    EXPECT_LE(std::abs(got - ref), 3 * se) << fmt::format("lambda_perp at z/a = {}: {} vs Brenner {} (SE {})", z, got, ref, se);
    if (z < 2.0) continue;  // Faxen's series is no reference closer than this
    const double ref_par = referenceValue("lambda_par", {{"z_over_a", z}, {"from", std::string("Faxen series")}});
    const double par = metric(s, "lambda_par_" + label), se_par = metric(s, "lambda_par_se_" + label);
    EXPECT_LE(std::abs(par - ref_par), 3 * se_par) << fmt::format("lambda_par at z/a = {}: {} vs Faxen {} (SE {})", z, par, ref_par, se_par);
  }
  // Near contact the drag rises steeply: the measured factors increase towards the wall.
  EXPECT_GT(metric(s, "lambda_par_1.128"), metric(s, "lambda_par_1.543"));
  EXPECT_GT(metric(s, "lambda_perp_1.128"), 3 * metric(s, "lambda_perp_1.543"));
}

// Check 8: sedimenting particles with non-sticky deposits fill the plate like ballistic
// deposition (rolling), clearly above random sequential adsorption.
TEST(WallChecks, BlockingSaturatesAtBallisticDepositionCoverage) {
  const RunSummary s = runShipped("physics-blocking.toml", "physics-blocking-run");
  EXPECT_TRUE(s.all_pass);
  EXPECT_TRUE(fs::exists(outDir("physics-blocking-run") / "coverage.csv"));
  const fs::path rsa = fs::path(MMVAL_SOURCE_DIR) / "reference-data" / "rsa-blocking.toml";
  const auto jamming = [&](const std::string& model) {
    const auto rows = loadReferenceFile(rsa).find("jamming_coverage", {{"model", model}});
    EXPECT_EQ(rows.size(), 1u);
    return rows.empty() ? std::nan("") : *rows.front()->value;
  };
  const double theta = metric(s, "coverage");
  // 3 seed standard deviations (0.0044, seeds 1-3) plus the finite window.
  EXPECT_NEAR(theta, jamming("BD"), 0.015);
  EXPECT_GT(theta - jamming("RSA"), 0.04) << "coverage " << theta << " is not distinguishable from RSA's";
  // No linear term in BD's blocking function: nearly every early arrival reaches the plate.
  EXPECT_GE(metric(s, "blocking_00_10"), 0.97);
  // The deposition probability falls as the plate fills.
  EXPECT_GT(metric(s, "blocking_20_30"), metric(s, "blocking_40_50"));
  // Attachments the engine made where a sphere does not fit stay a small minority (reported).
  EXPECT_LT(metric(s, "unplaced_deposits"), 0.06 * metric(s, "deposits"));
}

TEST(WallChecks, BadInputNamesTheKey) {
  const auto expectKey = [](const std::string& file, const std::vector<CaseOverride>& o, const std::string& key) {
    try {
      const Case c = Case::load(kCases / file, particleRegistry(), o);
      runCase(c, particleRegistry(), outDir("physics-wall-bad-input"), {.quiet = true});
      ADD_FAILURE() << "no InputError for " << key;
    } catch (const InputError& e) {
      EXPECT_EQ(e.where().key, key) << e.what();
    }
  };
  expectKey("physics-sedimentation-equilibrium.toml", {{"plates.gap", "1.2 um"}}, "plates.gap");
  expectKey("physics-sedimentation-equilibrium.toml", {{"run.duration", "20 s"}}, "run.duration");
  expectKey("physics-sedimentation-equilibrium.toml", {{"particles.density", "0.9 g/cm3"}}, "particles.density");
  expectKey("physics-hindered-diffusion.toml", {{"release.heights", "[0.9]"}}, "release.heights");
  expectKey("physics-hindered-diffusion.toml", {{"release.heights", "[1500.0]"}}, "release.heights");
  expectKey("physics-blocking.toml", {{"analysis.margin", "110 um"}}, "analysis.margin");
  expectKey("physics-blocking.toml", {{"plates.gap", "10 um"}}, "plates.gap");
}


// ---------------------------------------------------------------- the theory alone (WallTheory.hpp)

/// Composite Simpson of f over [lo, hi] with n (even) intervals.
template <class F>
double simpson(F f, double lo, double hi, int n) {
  const double dx = (hi - lo) / n;
  double sum = f(lo) + f(hi);
  for (int k = 1; k < n; ++k) sum += (k % 2 ? 4.0 : 2.0) * f(lo + k * dx);
  return sum * dx / 3;
}

// Boltzmann's truncated exponential: the closed-form mean against quadrature of z p(z), the
// quantile inverting the CDF (round-off class), for the sedimentation case's 1 um sphere in 5 um.
TEST(WallTheory, BarometricMeanAndQuantile) {
  const double a = 0.5e-6, h = 5e-6, ls = 0.7865e-6;
  const checks::Barometric ref{a, h - 2 * a, ls};
  const auto p = [&](double z) { return std::exp(-(z - a) / ls) / (ls * ref.norm()); };
  EXPECT_NEAR(simpson(p, a, h - a, 2000), 1.0, 1e-12);
  EXPECT_NEAR(simpson([&](double z) { return z * p(z); }, a, h - a, 2000) / ref.mean(), 1.0, 1e-12);
  for (const double u : {0.01, 0.3, 0.5, 0.99}) EXPECT_NEAR(ref.cdf(ref.quantile(u)), u, 1e-14) << "u = " << u;
}

// Kolmogorov's distribution at its tabulated critical values: Q(1.3581) = 0.05, Q(1.6276) = 0.01
// (large n, where Stephens' correction vanishes; the 4-5 digit critical values set the tolerance).
TEST(WallTheory, KolmogorovPValue) {
  const double n = 1e10;
  EXPECT_NEAR(checks::ksPValue(1.3581 / std::sqrt(n), n), 0.05, 1e-4);
  EXPECT_NEAR(checks::ksPValue(1.6276 / std::sqrt(n), n), 0.01, 1e-4);
  EXPECT_DOUBLE_EQ(checks::ksPValue(0.0, 100), 1.0);
}

// Independent heights drawn from Boltzmann (inverse CDF, seed fixed): the statistics accept them:
// mean within 3 standard errors, no snapshot correlation beyond noise, KS and chi-square p > 0.001.
TEST(WallTheory, SedimentationStatsAcceptBoltzmannSamples) {
  const double a = 0.5e-6, h = 5e-6;
  const checks::Barometric ref{a, h - 2 * a, 0.7865e-6};
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<std::vector<double>> z(40, std::vector<double>(200));
  for (auto& snap : z)
    for (double& v : snap) v = ref.quantile(u(rng));
  const checks::SedimentationStats st = checks::sedimentationStats(z, ref, 20);
  EXPECT_LE(std::abs(st.mean - ref.mean()), 3 * st.se);
  EXPECT_LT(std::abs(st.lag1), 0.05);  // ~1 / sqrt(8000) = 0.011 expected spread
  EXPECT_GT(st.ks_p, 1e-3);
  EXPECT_GT(st.chi2_p, 1e-3);
  EXPECT_EQ(st.samples, 8000);
  // Every sample lands in the histogram.
  std::istringstream csv(st.histogram_csv);
  std::string line;
  std::getline(csv, line);
  double counted = 0;
  while (std::getline(csv, line)) counted += std::stod(line.substr(line.find(',', line.find(',') + 1) + 1));
  EXPECT_EQ(counted, 8000.0);
}

// Sample variance and its standard error: for normal samples Var = sigma^2 and SE(Var) = sigma^2 sqrt(2 / n);
// 3 standard errors on the variance, 5 % on its error (the error of an error estimate at n = 1e5).
TEST(WallTheory, MomentsOfNormalSamples) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> g(0.3, 2.0);
  checks::Moments m;
  const int n = 100000;
  for (int k = 0; k < n; ++k) m.add(g(rng));
  const double se = 4.0 * std::sqrt(2.0 / n);
  EXPECT_NEAR(m.var(), 4.0, 3 * se);
  EXPECT_NEAR(m.varSe() / se, 1.0, 0.05);
}

// The mean height without the Ito drift: the log-spaced quadrature against plain Simpson on
// uniform grids (20000 intervals within 0.1 a of each plate, resolving the floor of the two-plate
// Brenner factor at gap 1e-3 a with 200 intervals, 2000 between), and below Boltzmann's mean (the
// missing drift piles particles up at the plates).
TEST(WallTheory, MeanHeightWithoutItoDrift) {
  const double a = 0.5e-6, h = 5e-6, floor = 1e-3 * a;
  const checks::Barometric ref{a, h - 2 * a, 0.7865e-6};
  const auto w = [&](double z) { return twoWallPerpendicular(a, std::clamp(z, a + floor, h - a - floor), h) * std::exp(-(z - a) / ref.ls); };
  const auto pieces = [&](auto f) {
    const double lo = a + 0.1 * a, hi = h - a - 0.1 * a;
    return simpson(f, a, lo, 20000) + simpson(f, lo, hi, 2000) + simpson(f, hi, h - a, 20000);
  };
  const double w0 = pieces(w), w1 = pieces([&](double z) { return z * w(z); });
  const double got = checks::meanHeightWithoutItoDrift(ref, h);
  EXPECT_NEAR(got / (w1 / w0), 1.0, 1e-4);
  EXPECT_LT(got, 0.8 * ref.mean());
}

}  // namespace
}  // namespace mmval::particles
