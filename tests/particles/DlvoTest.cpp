// DLVO library (simulate/particles Dlvo) against closed forms and literature:
// Debye lengths (Israelachvili), force = -dV/dh, the HHF limits, Derjaguin
// scaling between geometries, Gregory's and Ruckenstein-Prieve's limits, the
// critical coagulation condition and the Schulze-Hardy z^-6 rule (Verwey &
// Overbeek), the attachment integral against Laplace's estimate and the barrier's
// slope, the Maxwell capture fraction, robustness (no NaN) and the case kind.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>

#include <fmt/format.h>

#include "mmval/core/Case.hpp"
#include "mmval/core/ReferenceData.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/particles/Dlvo.hpp"
#include "mmval/particles/Kinds.hpp"
#include "mmval/particles/Physics.hpp"

namespace mmval::particles {
namespace {

namespace fs = std::filesystem;

constexpr double kEps0 = 8.8541878128e-12;
constexpr double kE = 1.602176634e-19;
const double kInf = std::numeric_limits<double>::infinity();

const ReferenceFile& profilesRef() { return loadReferenceFile(fs::path(MMVAL_SOURCE_DIR) / "reference-data" / "dlvo-profiles.toml"); }
const ReferenceFile& materialsRef() { return loadReferenceFile(fs::path(MMVAL_SOURCE_DIR) / "reference-data" / "dlvo-materials.toml"); }

double refValue(const ReferenceFile& f, const std::string& quantity, const AtMap& at) {
  const auto rows = f.find(quantity, at);
  if (rows.size() != 1 || !rows.front()->value) throw std::runtime_error("reference row not found: " + quantity + " " + toString(at));
  return *rows.front()->value;
}

DlvoParameters base() {
  DlvoParameters p;
  p.particle_radius = 2.5e-6;
  p.particle_potential = -0.025;
  p.collector_potential = -0.030;
  p.electrolyte.ionic_strength = 10.0;
  return p;
}

// Israelachvili prints 1/kappa = 0.304 / sqrt(M) nm (1:1) and 0.152 / sqrt(M) nm (2:2) at 25 C;
// three digits, so 0.5 % (rounding 0.2 %, eps_r of water 78.4-78.5 0.1 %).
TEST(Dlvo, DebyeLengthAgainstIsraelachvili) {
  for (double c_mM : {1.0, 10.0, 1000.0}) {
    Electrolyte e;
    e.ionic_strength = c_mM;
    const double ref = refValue(profilesRef(), "debye_length", {{"electrolyte", std::string("1:1")}, {"c_mM", c_mM}, {"T_C", 25.0}});
    EXPECT_NEAR(debyeLength(e) * 1e9, ref, 0.005 * ref) << "1:1 at " << c_mM << " mM";
  }
  Electrolyte e;
  e.valence = 2;
  e.ionic_strength = 4.0 * 10.0;  // I = c z^2 for a 2:2 salt at c = 10 mM
  const double ref = refValue(profilesRef(), "debye_length", {{"electrolyte", std::string("2:2")}, {"c_mM", 10.0}, {"T_C", 25.0}});
  EXPECT_NEAR(debyeLength(e) * 1e9, ref, 0.005 * ref);
  e.ionic_strength = -1;
  EXPECT_THROW(debyeLength(e), std::invalid_argument);
}

// Analytic forces against central differences of the energies, every term, both
// models and geometries, from 0.2 nm to 1 um. Round-off class: relative 1e-6.
TEST(Dlvo, ForceIsMinusEnergyGradient) {
  for (int model = 0; model < 2; ++model)
    for (double collector : {kInf, 1.5e-6})
      for (bool born : {false, true}) {
        DlvoParameters p = base();
        p.double_layer = model == 0 ? DoubleLayerModel::hhf : DoubleLayerModel::lsa;
        p.collector_radius = collector;
        p.born = born;
        const DlvoInteraction v(p);
        for (double h = 0.2e-9; h < 1e-6; h *= 1.3) {
          const double dh = 1e-6 * h;
          const auto check = [&](auto energy, double force, const char* what) {
            const double numerical = -(energy(h + dh) - energy(h - dh)) / (2 * dh);
            EXPECT_NEAR(force, numerical, 1e-6 * std::abs(force) + 1e-30) << what << " at h = " << h << " model " << model;
          };
          check([&](double x) { return v.doubleLayerEnergy(x); }, v.doubleLayerForce(h), "double layer");
          check([&](double x) { return v.vanDerWaalsEnergy(x); }, v.vanDerWaalsForce(h), "van der Waals");
          if (born) check([&](double x) { return v.bornEnergy(x); }, v.bornForce(h), "Born");
          check([&](double x) { return v.energy(x); }, v.force(h), "total");
        }
      }
}

// HHF at equal potentials is 4 pi eps R psi^2 ln(1 + exp(-kappa h)) (sphere-plate R = a);
// at low potentials and kappa h >> 1 both HHF and LSA tend to 4 pi eps R psi1 psi2 exp(-kappa h).
TEST(Dlvo, HhfLimits) {
  DlvoParameters p = base();
  p.double_layer = DoubleLayerModel::hhf;
  p.collector_potential = p.particle_potential;
  const DlvoInteraction v(p);
  const double eps = p.electrolyte.relative_permittivity * kEps0;
  for (double kh : {0.01, 0.1, 1.0, 5.0, 20.0}) {
    const double h = kh / v.kappa();
    const double closed = 4 * kPi * eps * p.particle_radius * p.particle_potential * p.particle_potential * std::log1p(std::exp(-kh));
    EXPECT_NEAR(v.doubleLayerEnergy(h), closed, 1e-12 * closed) << "kappa h = " << kh;
  }
  p.particle_potential = -0.002;
  p.collector_potential = -0.003;
  for (double kh : {8.0, 12.0}) {
    p.double_layer = DoubleLayerModel::hhf;
    const DlvoInteraction hhf(p);
    p.double_layer = DoubleLayerModel::lsa;
    const DlvoInteraction lsa(p);
    const double h = kh / hhf.kappa();
    const double far = 4 * kPi * eps * p.particle_radius * p.particle_potential * p.collector_potential * std::exp(-kh);
    // HHF's far field differs by O(exp(-kappa h)) (3e-4 at 8), LSA's tanh by (e psi / 4kT)^2 / 3 (~3e-4 at 3 mV).
    EXPECT_NEAR(hhf.doubleLayerEnergy(h) / far, 1.0, 1e-3);
    EXPECT_NEAR(lsa.doubleLayerEnergy(h) / far, 1.0, 1e-3);
  }
}

// At contact and low potentials LSA gives 4 pi eps R psi^2 and HHF (equal potentials)
// 4 pi eps R psi^2 ln 2: LSA lies above the constant-potential result there.
TEST(Dlvo, LsaAboveHhfAtContact) {
  DlvoParameters p = base();
  p.particle_potential = p.collector_potential = -0.001;
  p.double_layer = DoubleLayerModel::lsa;
  const DlvoInteraction lsa(p);
  p.double_layer = DoubleLayerModel::hhf;
  const DlvoInteraction hhf(p);
  const double h = 1e-6 / lsa.kappa();
  EXPECT_NEAR(hhf.doubleLayerEnergy(h) / lsa.doubleLayerEnergy(h), std::log(2.0), 1e-4);
}

// High potentials (LSA, -50 / -77 mV, 5 um): at 20 mM the double layer outweighs van der
// Waals down to the Born wall. The features must then report the barrier (from the
// Born-free profile), a secondary minimum beyond it and no primary minimum, and the
// attachment must say the primary minimum cannot be reached (alpha = 0), not alpha = 1.
TEST(Dlvo, BarrierMergedWithBornWallLeavesOnlyTheSecondaryMinimum) {
  DlvoParameters p;
  p.double_layer = DoubleLayerModel::lsa;
  p.particle_potential = -0.050;
  p.collector_potential = -0.077;
  p.electrolyte.ionic_strength = 20.0;
  const DlvoInteraction v(p);
  const auto f = profileFeatures(v);
  ASSERT_TRUE(f.has_barrier);
  EXPECT_TRUE(f.has_secondary_minimum);
  EXPECT_FALSE(f.has_primary_minimum);
  EXPECT_GT(f.barrier_kT, 100.0);
  EXPECT_LT(f.secondary_minimum_kT, 0.0);
  // Between the barrier and the well the full profile falls monotonically.
  for (double h = f.barrier_gap * 1.01; h < 0.99 * f.secondary_minimum_gap; h *= 1.05) EXPECT_GT(v.energy(h), v.energy(h * 1.05));
  const auto a = attachmentEfficiency(v);
  EXPECT_FALSE(a.primary_minimum_reachable);
  EXPECT_EQ(a.alpha(), 0.0);
  p.born = false;  // without Born the van der Waals singularity restores a reachable contact
  const auto free = attachmentEfficiency(DlvoInteraction(p));
  EXPECT_TRUE(free.primary_minimum_reachable);
  EXPECT_TRUE(std::isfinite(free.ln_alpha));
}

// Derjaguin: two spheres of radius a interact as a sphere of radius a/2 with a plate
// (double layer and van der Waals; Born uses its own sphere-plate form).
TEST(Dlvo, SphereSphereIsPlateWithDerjaguinRadius) {
  for (int model = 0; model < 2; ++model) {
    DlvoParameters p = base();
    p.double_layer = model == 0 ? DoubleLayerModel::hhf : DoubleLayerModel::lsa;
    p.born = false;
    p.collector_radius = p.particle_radius;
    const DlvoInteraction spheres(p);
    p.collector_radius = kInf;
    p.particle_radius *= 0.5;
    const DlvoInteraction plate(p);
    for (double h : {0.3e-9, 3e-9, 30e-9}) EXPECT_NEAR(spheres.energy(h), plate.energy(h), 1e-12 * std::abs(plate.energy(h)));
  }
}

// Gregory 1981: unretarded Hamaker-Derjaguin -A a / (6 h) as lambda -> inf, half of it at h = lambda / 14.
// Ruckenstein & Prieve 1976: for h << a the Born term is A sigma^6 a / (1260 h^7).
TEST(Dlvo, VanDerWaalsAndBornLimits) {
  DlvoParameters p = base();
  const DlvoInteraction v(p);
  const double h = p.retardation_wavelength / 14.0;
  EXPECT_NEAR(v.vanDerWaalsEnergy(h), -0.5 * p.hamaker * p.particle_radius / (6 * h), 1e-14);
  p.retardation_wavelength = 1e6;
  const DlvoInteraction unretarded(p);
  EXPECT_NEAR(unretarded.vanDerWaalsEnergy(1e-9) / (-p.hamaker * p.particle_radius / 6e-9), 1.0, 1e-6);
  const double hb = 0.3e-9;
  const double near = p.hamaker * std::pow(p.born_collision_diameter, 6) * p.particle_radius / (1260 * std::pow(hb, 7));
  EXPECT_NEAR(v.bornEnergy(hb) / near, 1.0, 1e-3);  // next term ~ h / (6 a) ~ 2e-5
}

/// Critical coagulation concentration by bisection on ln I: the largest I whose profile has a maximum above zero.
double numericalCcc(DlvoParameters p, double lo, double hi) {
  for (int i = 0; i < 40; ++i) {
    const double mid = std::sqrt(lo * hi);
    p.electrolyte.ionic_strength = mid;
    const DlvoInteraction v(p);
    const auto f = profileFeatures(v, 0.01e-9, 1e-6);
    (f.has_barrier && f.barrier_kT > 0 ? lo : hi) = mid;
  }
  return std::sqrt(lo * hi);
}

// LSA + unretarded van der Waals, no Born: V = B exp(-kappa h) - A a / (6 h). The barrier
// vanishes where V = V' = 0, i.e. kappa h = 1 and kappa = 6 B / (e A a) (Euler's e), the
// Derjaguin form of the DLVO critical coagulation concentration; at high potentials it
// scales as z^-6 in salt concentration (Schulze-Hardy; Verwey & Overbeek 1948).
TEST(Dlvo, CriticalCoagulationAndSchulzeHardy) {
  DlvoParameters p = base();
  p.double_layer = DoubleLayerModel::lsa;
  p.born = false;
  p.retardation_wavelength = 1e6;
  p.particle_potential = p.collector_potential = -0.3;
  double ccc_salt[2] = {0, 0};
  for (int z : {1, 2}) {
    p.electrolyte.valence = z;
    const double kT = kBoltzmann * p.electrolyte.temperature, eps = p.electrolyte.relative_permittivity * kEps0;
    const double g = std::tanh(z * kE * p.particle_potential / (4 * kT));
    const double B = 64 * kPi * eps * p.particle_radius * std::pow(kT / (z * kE), 2) * g * g;
    const double kappa_c = 6 * B / (std::exp(1.0) * p.hamaker * p.particle_radius);
    const double I_c = kappa_c * kappa_c * eps * kT / (2 * kE * kE * 6.02214076e23);
    const double I_num = numericalCcc(p, 1e-3 * I_c, 1e3 * I_c);
    EXPECT_NEAR(I_num / I_c, 1.0, 1e-4) << "z = " << z;
    p.electrolyte.ionic_strength = 0.999 * I_c;
    const DlvoInteraction v(p);
    const auto f = profileFeatures(v, 0.01e-9, 1e-6);
    ASSERT_TRUE(f.has_barrier);
    EXPECT_NEAR(v.kappa() * f.barrier_gap, 1.0, 0.05);  // -> 1 as I -> I_c (sqrt of the distance)
    ccc_salt[z - 1] = I_num / (z * z);
  }
  // tanh(z e psi / 4kT)^4 at -300 mV is 0.977 (z = 1) and 1.000 (z = 2): the ratio sits 2.3 % above 2^-6.
  const double ref = refValue(profilesRef(), "ccc_ratio", {{"valences", std::string("2:2 over 1:1")}});
  EXPECT_NEAR(ccc_salt[1] / ccc_salt[0], ref, 0.03 * ref);
}

// Features and attachment stay finite (or -inf for an unreachable primary minimum,
// by contract) over like and opposite charges, 0.1-1000 mM, both models, Born on/off.
TEST(Dlvo, FeaturesNeverNaN) {
  int with_barrier = 0, without = 0;
  for (double psi1 : {-0.08, -0.02, 0.0, 0.03})
    for (double psi2 : {-0.06, 0.04})
      for (double I : {0.1, 10.0, 1000.0})
        for (int model = 0; model < 2; ++model)
          for (bool born : {false, true}) {
            DlvoParameters p = base();
            p.particle_potential = psi1;
            p.collector_potential = psi2;
            p.electrolyte.ionic_strength = I;
            p.double_layer = model == 0 ? DoubleLayerModel::hhf : DoubleLayerModel::lsa;
            p.born = born;
            const DlvoInteraction v(p);
            const auto f = profileFeatures(v);
            for (double x : {f.barrier_kT, f.barrier_gap, f.secondary_minimum_kT, f.secondary_minimum_gap, f.primary_minimum_kT,
                             f.primary_minimum_gap})
              EXPECT_TRUE(std::isfinite(x));
            if (f.has_barrier && f.has_secondary_minimum) {
              EXPECT_GT(f.secondary_minimum_gap, f.barrier_gap);
            }
            if (f.has_barrier && f.has_primary_minimum) {
              EXPECT_LT(f.primary_minimum_gap, f.barrier_gap);
            }
            (f.has_barrier ? with_barrier : without)++;
            if (psi1 == -0.02 && I == 10.0 && born) {  // attachment on a subset (it costs ~30 ms a call)
              const auto a = attachmentEfficiency(v);
              EXPECT_FALSE(std::isnan(a.ln_alpha));
              EXPECT_TRUE(std::isfinite(a.ln_alpha) || !a.primary_minimum_reachable);
              if (psi2 > 0) {
                EXPECT_GE(a.ln_alpha, -1e-6) << "opposite charges attract: no barrier, alpha >= 1";
              }
            }
          }
  EXPECT_GT(with_barrier, 0);
  EXPECT_GT(without, 0);
}

// The barrier-limited rate: the quadrature against Laplace's estimate (exact to
// O(kT / Phi_max)), and the slope of ln alpha over ln I against the barrier's closed-form
// slope (envelope theorem) - the physics-dlvo case runs the full scan.
TEST(Dlvo, AttachmentAgainstLaplaceAndBarrierSlope) {
  DlvoParameters p = base();
  p.particle_potential = p.collector_potential = -0.025;
  p.double_layer = DoubleLayerModel::hhf;
  p.electrolyte.ionic_strength = 20.0;
  const DlvoInteraction v20(p);
  const auto a20 = attachmentEfficiency(v20);
  const auto f20 = profileFeatures(v20);
  ASSERT_TRUE(f20.has_barrier);
  EXPECT_GT(f20.barrier_kT, 100.0);
  EXPECT_NEAR(a20.ln_alpha, a20.ln_alpha_laplace, 0.01);
  p.electrolyte.ionic_strength = 40.0;
  const DlvoInteraction v40(p);
  const auto a40 = attachmentEfficiency(v40);
  EXPECT_GT(a40.ln_alpha, a20.ln_alpha) << "alpha must rise with ionic strength";
  p.electrolyte.ionic_strength = std::sqrt(20.0 * 40.0);
  const DlvoInteraction vm(p);
  const double theory = -barrierSlopeWithIonicStrength(vm, profileFeatures(vm));
  const double secant = (a40.ln_alpha - a20.ln_alpha) / std::log(2.0);
  EXPECT_NEAR(secant / theory, 1.0, 0.02) << "secant " << secant << " theory " << theory;

  // Two equal spheres (a deposit as collector): Fuchs' weight and Honig's resistance.
  p.collector_radius = p.particle_radius;
  p.electrolyte.ionic_strength = 20.0;
  const DlvoInteraction pair(p);
  const auto ap = attachmentEfficiency(pair);
  EXPECT_GT(profileFeatures(pair).barrier_kT, 100.0);
  EXPECT_NEAR(ap.ln_alpha, ap.ln_alpha_laplace, 0.01);
}

// Brenner's exact series hands over to Cox & Brenner's near-contact form at h/a = 0.01
// without a jump (their next terms are O((h/a) ln(h/a))^2 ~ 2e-3), and beta -> 1 far away.
TEST(Dlvo, NormalResistanceFactor) {
  DlvoParameters p = base();
  const DlvoInteraction plate(p);
  const double a = p.particle_radius;
  const double below = normalResistanceFactor(plate, 0.0099999 * a), above = normalResistanceFactor(plate, 0.01 * a);
  EXPECT_NEAR(below / above, 1.0, 5e-3);
  EXPECT_NEAR(normalResistanceFactor(plate, 1e-6 * a) * 1e-6, 1.0, 1e-4);  // lubrication: a / h
  EXPECT_NEAR(normalResistanceFactor(plate, 1000 * a), 1.0, 2e-3);
  p.collector_radius = a;
  const DlvoInteraction spheres(p);
  EXPECT_NEAR(normalResistanceFactor(spheres, 1e4 * a), 1.0, 1e-3);
  EXPECT_NEAR(normalResistanceFactor(spheres, 1e-6 * a) * 2e-6, 1.0, 1e-4);  // Honig: a / (2h) at contact
}

// P(3/2, x) against a direct quadrature of the Maxwell energy density 2 sqrt(t / pi) exp(-t).
TEST(Dlvo, SecondaryMinimumCaptureIsMaxwellFraction) {
  EXPECT_EQ(secondaryMinimumCaptureProbability(0.0), 0.0);
  EXPECT_EQ(secondaryMinimumCaptureProbability(-3.0), 0.0);
  for (double x : {0.1, 1.0, 1.5, 5.0, 20.0}) {
    const int n = 20000;  // Simpson in s = sqrt(t): integrand 4 s^2 exp(-s^2) / sqrt(pi), smooth
    const double s1 = std::sqrt(x), ds = s1 / n;
    double sum = 0;
    for (int i = 0; i <= n; ++i) {
      const double s = i * ds;
      const double w = (i == 0 || i == n) ? 1 : (i % 2 ? 4 : 2);
      sum += w * 4 * s * s * std::exp(-s * s) / std::sqrt(kPi);
    }
    EXPECT_NEAR(secondaryMinimumCaptureProbability(x), sum * ds / 3, 1e-10) << "x = " << x;
  }
  EXPECT_NEAR(secondaryMinimumCaptureProbability(50.0), 1.0, 1e-12);
}

// The default Hamaker constant is what Shaw's Eq. 8.12 gives from the upper ends of
// Table 8.3 (polystyrene 6.4, quartz 8.8, water at the low end 3.0, x 1e-20 J), rounded.
TEST(Dlvo, HamakerDefaultFollowsCombiningRule) {
  const auto range = [&](const std::string& material) {
    const auto rows = materialsRef().find("hamaker_constant", {{"material", material}});
    if (rows.size() != 1 || !rows.front()->low) throw std::runtime_error("no Hamaker row for " + material);
    return std::pair{*rows.front()->low, *rows.front()->high};
  };
  const auto [ps_lo, ps_hi] = range("polystyrene");
  const auto [q_lo, q_hi] = range("quartz");
  const auto [w_lo, w_hi] = range("water");
  (void)ps_lo, (void)q_lo, (void)w_hi;
  const double a132 = (std::sqrt(ps_hi) - std::sqrt(w_lo)) * (std::sqrt(q_hi) - std::sqrt(w_lo));
  const double def = refValue(materialsRef(), "hamaker_constant", {{"system", std::string("polystyrene-water-glass")}});
  EXPECT_NEAR(def, a132, 0.03 * def) << "Eq. 8.12 gives " << a132;
  EXPECT_DOUBLE_EQ(DlvoParameters{}.hamaker, def);
}

// The shipped physics-dlvo cases run and pass; bad input names its key.
TEST(Dlvo, CasesRunAndRejectBadInput) {
  CaseKindRegistry reg;
  registerParticleKinds(reg);
  for (const char* name : {"physics-dlvo", "physics-dlvo-latex-glass", "physics-dlvo-sphere-sphere", "physics-dlvo-peer"}) {
    const Case c = Case::load(fs::path(MMVAL_SOURCE_DIR) / "cases" / (std::string(name) + ".toml"), reg);
    const fs::path out = fs::path(MMVAL_BINARY_DIR) / "tests" / "particles" / (std::string(name) + "-run");
    const RunSummary s = runCase(c, reg, out, {.quiet = true});
    for (const auto& m : s.metrics) {
      if (m.pass) {
        EXPECT_TRUE(*m.pass) << name << ": " << m.name << " = " << m.value << " " << m.unit << ", tolerance " << m.tolerance;
      }
    }
    EXPECT_TRUE(s.all_pass) << name;
    EXPECT_TRUE(fs::exists(out / "attachment-vs-ionic-strength.csv"));
    EXPECT_TRUE(fs::exists(out / "dlvo-profile.csv"));
  }
  const fs::path file = fs::path(MMVAL_SOURCE_DIR) / "cases" / "physics-dlvo.toml";

  const Case reversed = Case::load(file, reg, {CaseOverride::parse("check.ionic_strengths=[\"5 mol/m3\", \"1 mol/m3\"]")});
  try {
    runCase(reversed, reg, fs::path(MMVAL_BINARY_DIR) / "tests" / "particles" / "physics-dlvo-bad", {.quiet = true});
    ADD_FAILURE() << "a decreasing scan was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("check.ionic_strengths"), std::string::npos) << e.what();
  }
  EXPECT_THROW(Case::load(file, reg, {CaseOverride::parse("chemistry.particle_zeta_mv=500")}), InputError);

  // A charge-regulated glass moves with the ionic strength, so the scan's fixed-potential
  // theory does not apply: the check refuses it, naming the key, instead of comparing.
  std::ifstream in(file);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto line = text.find("collector_zeta_mv = -25.0\n");
  ASSERT_NE(line, std::string::npos);
  text.replace(line, std::string("collector_zeta_mv = -25.0\n").size(), "collector_charge = \"regulated\"\n");
  const Case regulated = Case::parse(text, file, reg);
  try {
    runCase(regulated, reg, fs::path(MMVAL_BINARY_DIR) / "tests" / "particles" / "physics-dlvo-regulated", {.quiet = true});
    ADD_FAILURE() << "a regulated collector was compared with the fixed-potential slope";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("chemistry.collector_charge"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace mmval::particles
