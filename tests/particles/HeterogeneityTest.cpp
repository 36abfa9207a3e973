// Patchwise charge heterogeneity of the glass under deposition.model = "dlvo"
// (chemistry.favourable_fraction, lambda; Song, Johnson & Elimelech 1994, Environ. Sci. Technol.
// 28:1164): an arrival at a plate or grain lands on a favourable patch with probability lambda and
// attaches in the primary minimum, else the unfavourable DLVO rule decides, so the efficiency per
// arrival is alpha_eff = lambda + (1 - lambda) alpha_unf. Tested with one arrival per particle:
//   settling onto the bottom plate in still fluid (as in DepositionModelTest): at 3 mM the
//     unfavourable rule holds the Maxwell fraction P of the 1.5 kT secondary minimum (alpha over
//     the barrier ~ exp(-1.3e4)); each particle's fate follows from its own draw, and lambda = 0 is
//     the rule without heterogeneity particle by particle;
//   settling with no surface force at 1 mM (alpha_unf = 0, no secondary capture): the deposition
//     rate onto the plate is lambda times the Stokes settling flux, the rate of colloid filtration
//     theory (attachment efficiency times the transport rate; Yao, Habibian & O'Melia 1971).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "CaseScene.hpp"
#include "ParticleRegistry.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/particles/Dlvo.hpp"
#include "mmval/particles/OverdampedEngine.hpp"

namespace mmval::particles {
namespace {

SceneConfig glassScene(double ionic_strength_mM, double favourable_fraction) {
  SceneConfig c;
  c.brownian = false;
  c.wall_hindrance = false;  // Stokes settling: the arrival times below are analytic
  c.attachment.capture_distance = 0.1e-6;
  c.attachment.grains = false;
  c.attachment.rule = AttachmentModel::Rule::dlvo;
  c.attachment.chemistry.electrolyte.ionic_strength = ionic_strength_mM;
  c.attachment.chemistry.collector_potential = -0.077;
  c.attachment.chemistry.electrolyte.temperature = c.fluid.temperature;
  c.attachment.favourable_fraction = favourable_fraction;
  c.seed = 7;
  return c;
}

/// The engine's per-arrival draw, written out from its documented definition (splitmix64 of
/// seed, particle id and arrival number; OverdampedEngine::arrivalDraw): the oracle that says which
/// particle each rule must hold.
double arrivalDraw(std::uint64_t seed, std::int64_t id, std::uint32_t arrival) {
  std::uint64_t z = seed * 0x9E3779B97F4A7C15ULL ^ static_cast<std::uint64_t>(id) * 0xBF58476D1CE4E5B9ULL ^ (static_cast<std::uint64_t>(arrival) << 40);
  z += 0x9E3779B97F4A7C15ULL;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  z ^= z >> 31;
  return static_cast<double>(z >> 11) * 0x1.0p-53;
}

constexpr int kSide = 20, kN = kSide * kSide;

/// kN particles, one per 20 um column, settle onto the bottom plate in still fluid: one arrival each.
std::unique_ptr<OverdampedEngine> settle(const SceneConfig& c, const std::vector<double>& heights, double t_end) {
  const double a = c.particle.radius(), h = 42e-6 + 2 * a;
  auto e = std::make_unique<OverdampedEngine>(std::make_shared<UniformFlow>(Vec2(0, 0), h), c);
  std::vector<Vec3> xs;
  for (int k = 0; k < kN; ++k) xs.emplace_back((k % kSide) * 20e-6, (k / kSide) * 20e-6, heights[static_cast<std::size_t>(k)]);
  e->insert(xs);
  e->advance(t_end);
  return e;
}

std::vector<double> sameHeight(const SceneConfig& c) { return std::vector<double>(kN, c.particle.radius() + 20e-6); }

// 3 mM, lambda = 0, 0.1, 0.4. Every particle arrives once; its draw u decides: u < lambda attaches
// in the primary minimum (a favourable patch), else it is held in the secondary minimum when
// (u - lambda) / (1 - lambda) < P (the unfavourable rule on the rescaled draw), else it stays
// mobile. Checked particle by particle against the oracle (exact), and the fractions against
// alpha_eff = lambda + (1 - lambda) P and lambda within 4 binomial standard errors of 400 arrivals
// (0.098 at alpha_eff = 0.5; a fraction outside is a 6e-5 chance if the model holds). lambda = 0
// holds exactly the particles the rule without heterogeneity holds: the same draw, unchanged.
TEST(Heterogeneity, EachArrivalAttachesWithThePatchwiseEfficiency) {
  for (const double lambda : {0.0, 0.1, 0.4}) {
    const SceneConfig c = glassScene(3.0, lambda);
    const auto e = settle(c, sameHeight(c), 40.0);
    const SurfaceChemistry* sc = e->chemistry(Surface::bottom);
    ASSERT_NE(sc, nullptr);
    ASSERT_LT(sc->attachment.ln_alpha, -100.0);  // alpha_unf over the barrier: 0 in double
    const double p_sec = sc->secondary_capture;
    ASSERT_GT(p_sec, 0.3);
    ASSERT_LT(p_sec, 0.9);
    int primary = 0, secondary = 0, mismatched = 0;
    for (const auto& p : e->particles()) {
      ASSERT_EQ(p.arrivals, 1u) << "particle " << p.id << ": the test needs one arrival per particle";
      const double u = arrivalDraw(c.seed, p.id, 1);
      const bool want_primary = u < lambda;
      const bool want_secondary = !want_primary && (lambda > 0 ? (u - lambda) / (1 - lambda) : u) < p_sec;
      const bool held = p.status == ParticleStatus::deposited && p.held_by == Surface::bottom;
      mismatched += (held && !p.secondary) != want_primary || (held && p.secondary) != want_secondary ? 1 : 0;
      primary += held && !p.secondary ? 1 : 0;
      secondary += held && p.secondary ? 1 : 0;
    }
    EXPECT_EQ(mismatched, 0) << "lambda " << lambda;
    const double eff = patchwiseEfficiency(lambda, p_sec), frac = (primary + secondary) / double(kN);
    const double se = std::sqrt(eff * (1 - eff) / kN), se_l = std::sqrt(lambda * (1 - lambda) / kN);
    std::printf("lambda %.2f: %d primary + %d secondary of %d (%.3f), lambda + (1 - lambda) P = %.3f, 4 SE %.3f\n", lambda, primary, secondary,
                kN, frac, eff, 4 * se);
    EXPECT_NEAR(frac, eff, 4 * se) << "lambda " << lambda;
    EXPECT_NEAR(primary / double(kN), lambda, 4 * se_l) << "lambda " << lambda;
    if (lambda == 0) {
      EXPECT_EQ(primary, 0);
    }
  }
}

// Deposition rate onto a plate = alpha_eff x transport rate. 1 mM glass (barrier ~1.4e4 kT, well
// < 1 kT: alpha_unf = 0, no secondary capture) and no surface force (attraction_range 0), so the
// transport is Stokes settling alone, v_s = 2 (rho_p - rho_f) g a^2 / (9 mu), computed here: the
// particle released at height z arrives at t = (z - a - capture distance) / v_s. Heights spread
// evenly over 40 um make the arrival flux constant; the number attached by time t must be lambda
// times the number arrived, within 4 binomial standard errors, for two lambdas (rate doubles with
// lambda), and each attached particle attaches at its analytic arrival time within the 20 ms
// steps (its arrival falls in one step; 2 steps allowed for the step that ends after it). The
// step also shifts which particles count as arrived at t by at most a particle or two, below
// 1 SE. A rejected particle rests on the plate (no force lifts it): one arrival.
TEST(Heterogeneity, DepositionRateIsLambdaTimesTheSettlingFlux) {
  for (const double lambda : {0.15, 0.3}) {
    SceneConfig c = glassScene(1.0, lambda);
    c.attachment.attraction_range = 0;
    c.max_dt = 0.02;
    const double a = c.particle.radius(), cd = c.attachment.capture_distance;
    const double vs = 2.0 * (c.particle.density - c.fluid.density) * c.gravity * a * a / (9.0 * c.fluid.viscosity);
    std::vector<double> z(kN);
    for (int k = 0; k < kN; ++k) z[static_cast<std::size_t>((k * 173) % kN)] = a + cd + 0.5e-6 + 40e-6 * (k + 0.5) / kN;
    for (const double t : {20.0, 40.0, 70.0}) {
      const auto e = settle(c, z, t);
      int arrived = 0, attached = 0;
      for (const auto& p : e->particles()) {
        const double t_arrive = (z[static_cast<std::size_t>(p.id - 1)] - a - cd) / vs;
        arrived += t_arrive <= t ? 1 : 0;
        attached += p.status == ParticleStatus::deposited ? 1 : 0;
        ASSERT_LE(p.arrivals, 1u);
        if (p.status == ParticleStatus::deposited) {
          EXPECT_FALSE(p.secondary);
          // It attaches at its one arrival: in the step that takes it within the capture distance.
          EXPECT_GE(p.t_event, t_arrive - c.max_dt);
          EXPECT_LE(p.t_event, t_arrive + 2 * c.max_dt);
        }
      }
      ASSERT_GT(arrived, 50);
      const double se = std::sqrt(arrived * lambda * (1 - lambda));
      std::printf("lambda %.2f, t %.0f s: %d attached of %d arrived (Stokes), expected %.1f +- %.1f (4 SE)\n", lambda, t, attached, arrived,
                  lambda * arrived, 4 * se);
      EXPECT_NEAR(attached, lambda * arrived, 4 * se) << "lambda " << lambda << ", t " << t;
    }
  }
}

// Deposits are latex and keep their own chemistry: lambda = 1 makes every glass arrival attach and
// leaves the deposits' rule alone; the engine reports lambda and the efficiency it gives.
TEST(Heterogeneity, GlassOnlyAndReported) {
  const SceneConfig c = glassScene(1.0, 1.0);
  const auto e = settle(c, sameHeight(c), 40.0);
  int held = 0;
  for (const auto& p : e->particles()) held += p.status == ParticleStatus::deposited && p.held_by == Surface::bottom && !p.secondary ? 1 : 0;
  EXPECT_EQ(held, kN);
  const auto het = e->describe()["dlvo"]["charge_heterogeneity"];
  EXPECT_EQ(het["favourable_fraction"].get<double>(), 1.0);
  EXPECT_EQ(het["primary_attachment_efficiency"].get<double>(), 1.0);
  EXPECT_EQ(e->chemistry(Surface::deposit)->alpha, 0.0);  // latex-latex at 1 mM: the barrier stays

  EXPECT_DOUBLE_EQ(patchwiseEfficiency(0.25, 0.2), 0.25 + 0.75 * 0.2);
  EXPECT_EQ(patchwiseEfficiency(0.0, 0.3), 0.3);
  EXPECT_THROW(patchwiseEfficiency(-0.1, 0.3), std::invalid_argument);
  EXPECT_THROW(patchwiseEfficiency(0.5, 1.5), std::invalid_argument);
}

Case channelCase(const std::string& deposition_model, const std::string& lambda) {
  const std::string text = "[case]\nname = \"het\"\nkind = \"particles-channel\"\n[channel]\nlength = \"300 um\"\nwidth = \"100 um\"\n"
                           "[particles]\ncount = 3\n[deposition]\nmodel = \"" +
                           deposition_model + "\"\n[chemistry]\nfavourable_fraction = " + lambda + "\n";
  return Case::parse(text, "het.toml", test_support::particleRegistry());
}

std::string inputErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// The key: read under the dlvo rule, refused outside [0, 1] and with the capture rule, naming it.
TEST(Heterogeneity, CaseKeyIsValidated) {
  SceneConfig s;
  physicsAndDepositionFromCase(channelCase("dlvo", "0.01"), EngineChoice{}, s);
  EXPECT_EQ(s.attachment.favourable_fraction, 0.01);
  SceneConfig d;
  physicsAndDepositionFromCase(channelCase("dlvo", "0.0"), EngineChoice{}, d);
  EXPECT_EQ(d.attachment.favourable_fraction, 0.0);
  for (const char* bad : {"-0.1", "1.5"}) {
    const std::string msg = inputErrorOf([&] {
      SceneConfig x;
      physicsAndDepositionFromCase(channelCase("dlvo", bad), EngineChoice{}, x);
    });
    EXPECT_NE(msg.find("chemistry.favourable_fraction"), std::string::npos) << bad << ": " << msg;
  }
  const std::string msg = inputErrorOf([&] {
    SceneConfig x;
    physicsAndDepositionFromCase(channelCase("capture", "0.2"), EngineChoice{}, x);
  });
  EXPECT_NE(msg.find("chemistry.favourable_fraction"), std::string::npos) << msg;
}

}  // namespace
}  // namespace mmval::particles
