// Checks 3 and 4 of the particle physics against theory (simulate/particles/src/checks/SlitChecks.cpp):
// cases/physics-settling-slit.toml and cases/physics-diffusion-slit.toml load, run and meet
// their own acceptance entries (references: the closed-form trajectory integral, a quadrature of
// the engine's drift, the Graetz series and reference-data/slit-deposition.toml), and bad input
// is refused with an InputError naming the key. The theory functions themselves
// (SlitTheory.hpp) are tested directly against reference-data/slit-deposition.toml
// and closed forms.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "mmval/core/Case.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/ReferenceData.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/particles/Kinds.hpp"

#include "../../simulate/particles/src/checks/SlitTheory.hpp"

namespace mmval::particles {
namespace {

namespace fs = std::filesystem;

class SlitChecks : public ::testing::Test {
 protected:
  void SetUp() override { registerParticleKinds(m_reg); }

  Case load(const std::string& name, const std::vector<std::string>& sets = {}) const {
    std::vector<CaseOverride> overrides;
    for (const auto& s : sets) overrides.push_back(CaseOverride::parse(s));
    return Case::load(fs::path(MMVAL_SOURCE_DIR) / "cases" / (name + ".toml"), m_reg, overrides);
  }

  RunSummary run(const std::string& name) const {
    const fs::path out = fs::path(MMVAL_BINARY_DIR) / "tests" / "particles" / (name + "-run");
    const RunSummary s = runCase(load(name), m_reg, out, {.quiet = true});
    for (const auto& m : s.metrics)
      std::cout << m.name << " = " << m.value << " " << m.unit << (m.pass ? (*m.pass ? "  PASS" : "  FAIL") : "") << "\n";
    return s;
  }

  /// The InputError the kind's runner throws for `name` with `sets` applied (empty key when none).
  std::string inputErrorKey(const std::string& name, const std::vector<std::string>& sets) const {
    const Case c = load(name, sets);
    RunContext ctx;
    ctx.out_dir = fs::path(MMVAL_BINARY_DIR) / "tests" / "particles" / (name + "-bad");
    fs::create_directories(ctx.out_dir);
    try {
      m_reg.find(c.kind())->run(c, ctx);
    } catch (const InputError& e) {
      std::cout << e.what() << "\n";
      return e.where().key;
    }
    return {};
  }

  static std::vector<std::string> csvRows(const fs::path& file) {
    std::ifstream in(file);
    std::vector<std::string> rows;
    for (std::string line; std::getline(in, line);) rows.push_back(line);
    return rows;
  }

  CaseKindRegistry m_reg;
};

TEST_F(SlitChecks, SettlingCaseMeetsTheTrajectoryIntegral) {
  const RunSummary s = run("physics-settling-slit");
  EXPECT_TRUE(s.all_pass);
  // The curve: a header and one row per analysis point (50).
  const auto rows = csvRows(fs::path(MMVAL_BINARY_DIR) / "tests" / "particles" / "physics-settling-slit-run" / "settling-deposition.csv");
  ASSERT_EQ(rows.size(), 51u);
  EXPECT_EQ(rows.front().rfind("length_mm,fraction_point,fraction_point_reference", 0), 0u);
}

TEST_F(SlitChecks, DiffusionCaseMeetsTheGraetzSeries) {
  const RunSummary s = run("physics-diffusion-slit");
  EXPECT_TRUE(s.all_pass);
  const auto rows = csvRows(fs::path(MMVAL_BINARY_DIR) / "tests" / "particles" / "physics-diffusion-slit-run" / "diffusion-penetration.csv");
  ASSERT_EQ(rows.size(), 6u);  // header + 5 lengths
  EXPECT_EQ(rows.front().rfind("mu,length_um,penetration,penetration_se,penetration_graetz", 0), 0u);
}

// The diffusion check can fail: hindered diffusion near the plates (Brenner's lambda_perp ~ a / gap
// down to the 0.02 um capture gap) is a resistance the Graetz series does not have, and lowers the
// deposition far beyond the statistical error (measured with 3000 particles: P 0.55 instead of
// 0.40 at mu' = 0.1, mean Sherwood number 6.0 instead of 9.2).
TEST_F(SlitChecks, DiffusionCheckDetectsHinderedDiffusion) {
  const Case c = load("physics-diffusion-slit", {"physics.wall_hindrance=true", "particles.count=1000", "numerics.step_check_factor=0",
                                                  "analysis.mu=[0.01, 0.05]"});
  const RunSummary s = runCase(c, m_reg, fs::path(MMVAL_BINARY_DIR) / "tests" / "particles" / "physics-diffusion-slit-hindered", {.quiet = true});
  double z = 0;
  for (const auto& m : s.metrics)
    if (m.name == "penetration_max_abs_z") z = m.value;
  std::cout << "penetration_max_abs_z with hindered diffusion = " << z << "\n";
  EXPECT_GT(z, 5.0);
  EXPECT_FALSE(s.all_pass);
}

TEST_F(SlitChecks, ParticlesThatDoNotFitAreAnInputError) {
  EXPECT_EQ(inputErrorKey("physics-settling-slit", {"particles.diameter=\"12 um\""}), "particles.diameter");
  EXPECT_EQ(inputErrorKey("physics-diffusion-slit", {"particles.diameter=\"10 um\""}), "particles.diameter");
}

TEST_F(SlitChecks, BadLengthsAndStepsAreInputErrors) {
  EXPECT_EQ(inputErrorKey("physics-diffusion-slit", {"analysis.mu=[0.1, 0.05]"}), "analysis.mu");
  EXPECT_EQ(inputErrorKey("physics-diffusion-slit", {"numerics.max_step_fraction=0.8"}), "numerics.step_check_factor");
  EXPECT_EQ(inputErrorKey("physics-settling-slit", {"particles.density=\"0.9 g/cm3\""}), "particles.density");
}


// ---------------------------------------------------------------- the theory alone (SlitTheory.hpp)

/// The point-particle series with 40 modes (as the diffusion check computes it), once.
const checks::GraetzSeries& pointSeries() {
  static const checks::GraetzSeries g = checks::graetzSeries(40, 1.0, 1.0);
  return g;
}

double slitReference(const std::string& quantity, const AtMap& at = {}) {
  const auto rows = loadReferenceFile(fs::path(MMVAL_SOURCE_DIR) / "reference-data" / "slit-deposition.toml").find(quantity, at);
  EXPECT_EQ(rows.size(), 1u) << quantity << " " << toString(at);
  return rows.empty() || !rows.front()->value ? std::nan("") : *rows.front()->value;
}

// The point-particle Graetz eigenproblem against Shah & London's eigenvalues (7 digits stored:
// tolerance 1e-6 relative, the last digit), the penetration weights (4 digits: half a unit of the
// last, 5e-5) and the fully developed Nusselt number (8/3) lambda_1^2 = 7.5407 (5 digits).
TEST(SlitTheory, GraetzSeriesMatchesShahAndLondon) {
  const checks::GraetzSeries& g = pointSeries();
  ASSERT_EQ(g.lambda.size(), 40u);
  for (int n = 1; n <= 3; ++n) {
    const double lambda_ref = slitReference("graetz_eigenvalue", {{"n", static_cast<double>(n)}});
    EXPECT_NEAR(g.lambda[n - 1] / lambda_ref, 1.0, 1e-6) << "n = " << n;
    EXPECT_NEAR(g.weight[n - 1], slitReference("graetz_penetration_weight", {{"n", static_cast<double>(n)}}), 5e-5) << "n = " << n;
  }
  EXPECT_NEAR(8.0 / 3.0 * g.lambda[0] * g.lambda[0] / slitReference("nusselt_fully_developed"), 1.0, 1e-5);
  EXPECT_DOUBLE_EQ(g.entry_fraction, 1.0);
  // Nothing enters without penetrating: P(0) = sum G_n, which 40 modes bring to within 1 % of 1
  // (the weights fall off as n^(-7/3) near the entrance singularity).
  EXPECT_NEAR(g.penetration(0.0), 1.0, 0.01);
}

// Leveque's coefficient 3 (2/3)^(1/3) / Gamma(4/3) = 2.9348 (4 digits stored), and the series
// tends to it at short lengths: at mu' = 1e-4 the deposited fractions agree to 1 %.
TEST(SlitTheory, LevequeLimitOfTheSeries) {
  const double mu = 1e-4;
  EXPECT_NEAR((1 - checks::levequePenetration(mu)) / std::pow(mu, 2.0 / 3.0), slitReference("leveque_coefficient"), 5e-5);
  EXPECT_NEAR((1 - pointSeries().penetration(mu)) / (1 - checks::levequePenetration(mu)), 1.0, 0.01);
}

// Settling of point particles: f = L v_s / (h U) (Fuchs 1964), the stored row at 0.5; the
// closed form with the particle's size tends to it as a, c -> 0 (round-off class tolerance).
TEST(SlitTheory, PointFractionTendsToFuchs) {
  const double h = 20e-6, U = 1e-3, vs = 1e-5;
  const double L = 0.5 * h * U / vs;
  EXPECT_NEAR(checks::pointFraction(L, h, U, vs, 1e-15, 1e-15), slitReference("settling_deposited_fraction", {{"L_vs_over_hU", 0.5}}), 1e-9);
  EXPECT_DOUBLE_EQ(checks::pointFraction(3 * L, h, U, vs, 1e-15, 1e-15), 1.0);
  // A finite particle catches the flux entering below its capture height at once: f(0) > 0.
  EXPECT_GT(checks::pointFraction(0.0, h, U, vs, 1e-6, 0.1e-6), 0.0);
}

// The trajectory quadrature and the entering flux for a drift given in closed form: plane
// Poiseuille flow with free settling, where X(z0) = (h U / v_s) (F(s0) - F(s_c)) and the flux
// below z is (F(z/h) - F(a/h)) / (F(1 - a/h) - F(a/h)). Tolerances: the quadrature's own
// 1e-9 of the scale, the 20000-cell trapezoid's ~1e-8.
TEST(SlitTheory, TrajectoryQuadratureAndFluxOfPoiseuilleSettling) {
  const double h = 20e-6, U = 1e-3, vs = 1e-5, a = 1e-6, c = 0.1e-6, scale = h * U / vs;
  const checks::DriftAt drift = [&](double z) { return Vec3(6 * U * z / h * (1 - z / h), 0.0, -vs); };
  using checks::cubicF;
  for (const double z0 : {2e-6, 8e-6, 15e-6}) {
    const double exact = scale * (cubicF(z0 / h) - cubicF((a + c) / h));
    EXPECT_NEAR(checks::trajectoryDistance(drift, z0, a, c, scale), exact, 1e-8 * scale) << "z0 = " << z0;
  }
  const checks::EntryFlux flux(drift, a, h);
  for (const double z : {3e-6, 10e-6, 18e-6}) {
    const double exact = (cubicF(z / h) - cubicF(a / h)) / (cubicF(1 - a / h) - cubicF(a / h));
    EXPECT_NEAR(flux.fractionBelow(z), exact, 1e-8) << "z = " << z;
    EXPECT_NEAR(flux.quantile(exact), z, 1e-8 * h) << "z = " << z;
  }
  // The quadrature reference and the closed form (3) agree for this drift at any length.
  for (const double L : {0.2 * scale, 0.6 * scale})
    EXPECT_NEAR(checks::trajectoryFraction(drift, flux, L, a, c, h, scale), checks::pointFraction(L, h, U, vs, a, c), 1e-7) << "L = " << L;
}

// The numerics: Simpson against int_0^pi sin = 2, bisection against cbrt(2).
TEST(SlitTheory, QuadratureAndBisection) {
  EXPECT_NEAR(checks::integrate([](double x) { return std::sin(x); }, 0.0, std::acos(-1.0), 1e-12), 2.0, 1e-10);
  EXPECT_EQ(checks::integrate([](double) { return 1.0; }, 1.0, 1.0, 1e-12), 0.0);
  EXPECT_NEAR(checks::bisect([](double x) { return x * x * x - 2; }, 0.0, 2.0, 1e-14), std::cbrt(2.0), 1e-13);
}

}  // namespace
}  // namespace mmval::particles
