// Check 5 of docs/validation/particle-physics.md: single-collector efficiency of a post in its Kuwabara cell
// against fibre-filtration theory. The shipped cases (cases/physics-collector-*.toml)
// run through runCase and must meet their acceptance entries; the theory the runner
// prints is compared with reference-data/fibre-filtration.toml (values evaluated
// independently of the runner's code); bad input names its key.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "mmval/core/Case.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/ReferenceData.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/particles/Kinds.hpp"

#include "../TestScratch.hpp"
#include "../../simulate/particles/src/checks/CollectorSetup.hpp"

namespace mmval::particles {
namespace {

namespace fs = std::filesystem;

const fs::path kSource = fs::path(MMVAL_SOURCE_DIR);

/// A CSV with a header row, as columns by name.
std::map<std::string, std::vector<double>> readCsv(const fs::path& file) {
  std::ifstream in(file);
  std::string line;
  std::getline(in, line);
  std::vector<std::string> names;
  std::stringstream hs(line);
  for (std::string n; std::getline(hs, n, ',');) names.push_back(n);
  std::map<std::string, std::vector<double>> cols;
  while (std::getline(in, line)) {
    std::stringstream ls(line);
    std::size_t k = 0;
    for (std::string v; std::getline(ls, v, ',') && k < names.size(); ++k) cols[names[k]].push_back(std::stod(v));
  }
  return cols;
}

RunSummary runShipped(const std::string& name, const CaseKindRegistry& reg) {
  const Case c = Case::load(kSource / "cases" / (name + ".toml"), reg);
  const RunSummary s = runCase(c, reg, test::scratch(name), {.quiet = true});
  for (const auto& m : s.metrics)
    std::cout << m.name << " = " << m.value << " " << m.unit << (m.pass ? (*m.pass ? "  PASS" : "  FAIL") : "") << "\n";
  return s;
}

double referenceValue(const std::string& quantity, const AtMap& at) {
  const auto& ref = loadReferenceFile(kSource / "reference-data" / "fibre-filtration.toml");
  const auto rows = ref.find(quantity, at);
  if (rows.size() != 1 || !rows.front()->value) throw std::runtime_error("no unique reference row for " + quantity + " " + toString(at));
  return *rows.front()->value;
}

class CollectorCheck : public ::testing::Test {
 protected:
  void SetUp() override { registerParticleKinds(m_reg); }
  CaseKindRegistry m_reg;
};

// Streamline-following particles (Brownian motion off): the grazing trajectory's offset
// against the exact Kuwabara interception, R = 0.02-0.2. The runner's theory column
// must match the values stored in the reference data (evaluated from the stream function
// outside mmval, 5 digits), and every measured eta must be within 1 % of it (the case's
// own tolerance is the worst over the sweep).
TEST_F(CollectorCheck, InterceptionMatchesKuwabara) {
  const RunSummary s = runShipped("physics-collector-interception", m_reg);
  EXPECT_TRUE(s.all_pass);
  const auto cols = readCsv(test::scratch("physics-collector-interception") / "collector-interception.csv");
  ASSERT_EQ(cols.at("R").size(), 4u);
  for (std::size_t i = 0; i < 4; ++i) {
    const double r = cols.at("R_capture")[i];
    const double ref = referenceValue("eta_R", {{"phi", 0.1}, {"R", r}});
    EXPECT_NEAR(cols.at("eta_theory_kuwabara")[i] / ref, 1.0, 1e-4) << "R = " << r;  // 5 stored digits
    // Explicit Euler steps of 0.01 radii: first-order error measured at 0.2-0.5 % (3 % at 0.1 radii).
    EXPECT_NEAR(cols.at("eta_measured")[i] / ref, 1.0, 0.01) << "R = " << r;
    // Interception grows ~R^2: Lee & Liu's small-R form (1 - phi)/Ku R^2/(1 + R) is 4.7 % below the exact value at R = 0.2.
    EXPECT_NEAR(cols.at("eta_measured")[i] / cols.at("eta_theory_lee_liu")[i], 1.0, 0.06) << "R = " << r;
  }
}

// Brownian capture at Pe = 200, 600, 2000 against Stechkina, Kirsch & Fuchs and the -2/3 law.
TEST_F(CollectorCheck, DiffusionMatchesStechkinaFuchs) {
  const RunSummary s = runShipped("physics-collector-diffusion", m_reg);
  EXPECT_TRUE(s.all_pass);
  const auto cols = readCsv(test::scratch("physics-collector-diffusion") / "collector-diffusion.csv");
  ASSERT_EQ(cols.at("Pe").size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    const double pe = cols.at("Pe")[i];
    const double ref = referenceValue("eta", {{"phi", 0.1}, {"R", 0.0102}, {"Pe", pe}});
    EXPECT_NEAR(cols.at("eta_theory")[i] / ref, 1.0, 1e-4) << "Pe = " << pe;
    // Each point within 3 binomial standard errors plus the correlation's 10 % spread (2.9 vs Lee & Liu's 2.6)
    // and the engine's per-step capture check (up to 8 % low at Pe = 2000, measured; see the case file).
    const double tol = 3 * cols.at("eta_std_error")[i] + 0.18 * ref;
    EXPECT_NEAR(cols.at("eta_measured")[i], ref, tol) << "Pe = " << pe;
    // The release band held every captured particle with room to spare.
    EXPECT_LT(cols.at("outermost_capture_over_band")[i], 1.0);
  }
}

// The same search in the square array's flow solved by mmval's fluid solver (coarse grid, R = 0.2
// only): the solved flow must carry the Sangani & Acrivos (1982) permeability at phi = 0.1, which
// checks the scaling to face velocity, and the array captures more than the cell model by about
// the margin measured on 192 and 384 cells (+11.7 %, +11.2 %; a regression bound, not theory).
TEST_F(CollectorCheck, SquareArrayFlowAgainstKuwabara) {
  std::vector<CaseOverride> set;
  for (const char* s : {"collector.square_array=true", "numerics.array_cells=96", "sweep.interception=[0.2]", "search.rounds=3"})
    set.push_back(CaseOverride::parse(s));
  const Case c = Case::load(kSource / "cases" / "physics-collector-interception.toml", m_reg, set);
  const RunSummary s = runCase(c, m_reg, test::scratch("collector-array"), {.quiet = true});
  const auto& info = s.result["details"]["square_array"];
  std::cout << info.dump(1) << "\n";
  const double k = info["permeability_over_L2"].get<double>();
  const auto& ref = loadReferenceFile(kSource / "reference-data" / "square-array-permeability.toml");
  const auto rows = ref.find("k_over_L2", {{"phi", 0.10}});
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_NEAR(k / *rows.front()->value, 1.0, 0.02) << "96 cells across the period (34 per post diameter)";
  const auto cols = readCsv(test::scratch("collector-array") / "collector-interception.csv");
  ASSERT_EQ(cols.at("R").size(), 1u);
  const double ratio = cols.at("eta_square_array")[0] / cols.at("eta_theory_kuwabara")[0];
  EXPECT_GT(ratio, 1.0);
  EXPECT_LT(ratio, 1.25);
}

// Heun's drift (numerics.drift_integrator = "heun") against Euler's on the grazing trajectory:
// the exact Kuwabara interception is the reference, the step is halved twice from 0.2 radii.
// Euler's steps drift outward along the post's curved streamlines by ~ step^2 / (2 R_curv) each,
// an error first order in the step (measured when written, R = 0.02: -5.7 / -4.0 / -2.2 %);
// Heun's predictor-corrector cancels that term (+0.14 / +0.05 / +0.02 %): at every step it must
// be at least 10 x closer to the theory than Euler, and its observed order over the two halvings
// at least 1.25 and 0.5 above Euler's (1.42 against 0.68 when written; not 2, as the steps near
// the post are set by the gap, and the search's bracket adds its own granularity).
TEST_F(CollectorCheck, HeunDriftConvergesFasterThanEuler) {
  const auto error = [&](const char* integrator, double step) {
    std::vector<CaseOverride> set;
    for (const std::string& s : {std::string("sweep.interception=[0.02]"), "numerics.max_step_fraction=" + std::to_string(step),
                                 std::string("numerics.drift_integrator=\"") + integrator + "\""})
      set.push_back(CaseOverride::parse(s));
    const Case c = Case::load(kSource / "cases" / "physics-collector-interception.toml", m_reg, set);
    const RunSummary r = runCase(c, m_reg, test::scratch(std::string("collector-") + integrator), {.quiet = true});
    const double e = r.result["details"]["points"][0]["relative_error"].get<double>();
    std::cout << integrator << " at " << step << " radii: " << 100 * e << " %\n";
    return std::abs(e);
  };
  std::vector<double> euler, heun;
  for (const double step : {0.2, 0.1, 0.05}) {
    euler.push_back(error("euler", step));
    heun.push_back(error("heun", step));
    EXPECT_LT(heun.back(), 0.1 * euler.back()) << "step " << step;
  }
  // Observed orders over the two halvings (0.2 -> 0.05 radii): Heun 1.42, Euler 0.68 when written.
  const double order_heun = std::log2(heun.front() / heun.back()) / 2, order_euler = std::log2(euler.front() / euler.back()) / 2;
  EXPECT_GT(order_heun, 1.25);
  EXPECT_GT(order_heun, order_euler + 0.5);
  EXPECT_LT(heun.back(), 5e-4);
}

// A capture radius that reaches far into the cell is refused, naming the key.
TEST_F(CollectorCheck, CaptureRadiusBeyondTheCellIsAnInputError) {
  const std::string text = R"(
[case]
name = "bad-collector"
kind = "physics-collector-interception"
[collector]
solid_fraction = 0.4
[sweep]
interception = [0.5]
)";
  const Case c = Case::parse(text, test::scratch("bad-collector.toml"), m_reg);
  try {
    runCase(c, m_reg, test::scratch("bad-collector"), {.quiet = true});
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().key, "sweep.interception") << e.what();
  }
}


// ---------------------------------------------------------------- the theory alone (CollectorFlow.hpp, CollectorSetup.hpp)

// Kuwabara's factor and the exact interception at phi = 0.1 against the values stored in the
// reference data (evaluated outside mmval, 5 digits: 1e-4 relative).
TEST(CollectorTheory, KuwabaraFactorAndInterception) {
  EXPECT_NEAR(checks::kuwabaraFactor(0.1) / referenceValue("Ku", {{"phi", 0.1}}), 1.0, 1e-4);
  for (const double r : {0.0202, 0.0502, 0.1002, 0.2002})
    EXPECT_NEAR(checks::interceptionKuwabara(0.1, r) / referenceValue("eta_R", {{"phi", 0.1}, {"R", r}}), 1.0, 1e-4) << "R = " << r;
  // The stream function vanishes with its slope on the post (no slip): f(1) = f'(1) = 0.
  EXPECT_NEAR(checks::kuwabaraStream(0.1, 1.0), 0.0, 1e-14);
  EXPECT_NEAR(checks::kuwabaraStreamSlope(0.1, 1.0), 0.0, 1e-14);
}

// Stechkina, Kirsch & Fuchs' sum eta_D + eta_DR + eta_R at the diffusion case's R and Pe against the
// stored values (5 digits).
TEST(CollectorTheory, StechkinaFuchsEfficiency) {
  for (const double pe : {200.0, 600.0, 2000.0}) {
    const double r = 0.0102;
    const double eta = checks::diffusionStechkina(0.1, pe) + checks::interactionStechkina(0.1, pe, r) + checks::interceptionKuwabara(0.1, r);
    EXPECT_NEAR(eta / referenceValue("eta", {{"phi", 0.1}, {"R", r}, {"Pe", pe}}), 1.0, 1e-4) << "Pe = " << pe;
  }
}

// The weighted power-law fit: an exact power law gives its exponent (round-off class), and with equal
// weights the slope's standard error is the textbook sqrt(n / (n Sxx - Sx^2)) in ln x.
TEST(CollectorTheory, PowerLawFit) {
  const std::vector<double> pe{200, 600, 2000, 6000};
  std::vector<double> eta, rel(pe.size(), 1.0);
  for (const double p : pe) eta.push_back(2.9 * std::pow(p, -2.0 / 3.0));
  const auto [slope, se] = checks::fitPowerLaw(pe, eta, rel);
  EXPECT_NEAR(slope, -2.0 / 3.0, 1e-12);
  double sx = 0, sxx = 0;
  for (const double p : pe) sx += std::log(p), sxx += std::log(p) * std::log(p);
  const double n = static_cast<double>(pe.size());
  EXPECT_NEAR(se, std::sqrt(n / (n * sxx - sx * sx)), 1e-12);
  // Equal relative errors of 10 % leave the slope and scale its standard error by 0.1.
  const auto [slope10, se10] = checks::fitPowerLaw(pe, eta, std::vector<double>(pe.size(), 0.1));
  EXPECT_NEAR(slope10, slope, 1e-12);
  EXPECT_NEAR(se10, 0.1 * se, 1e-12);
}

}  // namespace
}  // namespace mmval::particles
