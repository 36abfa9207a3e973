// Arrivals under deposition.model = "dlvo" do not multiply as the step shrinks
// (AttachmentModel::release_distance). Each arrival at a surface draws once; after a rejection the
// particle must leave that surface to beyond the release distance (default one radius) before its
// next arrival there draws again. Under the former rule (release at the capture distance itself,
// release_distance <= capture_distance) a Brownian particle resting near the plate crosses the
// capture distance more and more often as dt falls (the level crossings of a discretised Brownian
// path grow like dt^-1/2), and each crossing drew again.
//
// Fixed chemistry with a known efficiency: 1 mM glass (barrier ~1.4e4 kT: alpha = 0; well < 1 kT: no
// secondary capture) and no surface force (attraction_range 0), with charge heterogeneity lambda,
// so an arrival attaches with probability lambda exactly (HeterogeneityTest). Particles of the
// case's latex (5 um, 1.05 g/cm3) settle with Brownian motion and wall hindrance onto the bottom
// plate of still fluid. Their sedimentation length k_B T / (m_b g) = 0.13 um is 1/19 of the release
// distance (a = 2.5 um): a rejected particle comes back up to a radius with probability ~exp(-19),
// so each particle arrives once and the attached fraction is 1 - (1 - lambda)^1 = lambda.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>

#include "mmval/particles/OverdampedEngine.hpp"

namespace mmval::particles {
namespace {

constexpr int kSide = 20, kN = kSide * kSide;
constexpr double kLambda = 0.3;

SceneConfig plateScene(double step_fraction, double release_distance) {
  SceneConfig c;
  c.max_step_fraction = step_fraction;
  c.attachment.capture_distance = 0.1e-6;
  c.attachment.grains = false;
  c.attachment.rule = AttachmentModel::Rule::dlvo;
  c.attachment.chemistry.electrolyte.ionic_strength = 1.0;
  c.attachment.chemistry.collector_potential = -0.077;
  c.attachment.chemistry.electrolyte.temperature = c.fluid.temperature;
  c.attachment.attraction_range = 0;
  c.attachment.favourable_fraction = kLambda;
  c.attachment.release_distance = release_distance;
  c.seed = 11;
  return c;
}

struct Outcome {
  int attached = 0;
  double arrivals = 0;  // mean per particle
};

/// kN particles, one per 20 um column, released 4 um above the bottom plate of a 30 um deep slit
/// of still fluid; the state after 60 s (settling 4 um at 0.68 um/s takes ~6 s plus the slowed
/// last approach; the rest is time spent resting on the plate).
/// Inserts `xs` into `e`, runs it for `t_end` s and counts the attached particles and the mean
/// arrivals per particle.
Outcome outcome(OverdampedEngine& e, const std::vector<Vec3>& xs, double t_end) {
  e.insert(xs);
  e.advance(t_end);
  Outcome o;
  for (const auto& p : e.particles()) {
    o.attached += p.status == ParticleStatus::deposited ? 1 : 0;
    o.arrivals += p.arrivals;
  }
  o.arrivals /= kN;
  return o;
}

Outcome settle(const SceneConfig& c) {
  const double a = c.particle.radius(), h = 30e-6;
  OverdampedEngine e(std::make_shared<UniformFlow>(Vec2(0, 0), h), c);
  std::vector<Vec3> xs;
  for (int k = 0; k < kN; ++k) xs.emplace_back((k % kSide) * 20e-6, (k / kSide) * 20e-6, a + 4e-6);
  return outcome(e, xs, 60.0);
}

// New rule (release one radius): at max_step_fraction 0.5, 0.2 and 0.1 every particle arrives
// once, so the attached fraction equals lambda within 4 binomial standard errors of 400 arrivals
// (0.092; outside is a 6e-5 chance) and is the same at the three steps (the same first draw of each
// particle decides: equal particle by particle, so within 0 SE; 1 SE allowed for a particle whose
// arrival falls after 60 s at one step).
// Former rule (release_distance = capture_distance): the mean number of arrivals per particle grows
// as the step shrinks and the attached fraction with it, beyond lambda by far more than 4 SE at 0.1
// radii: the check that fails the former rule.
TEST(ArrivalConvergence, OneArrivalPerSettledParticleAtEveryStep) {
  const double se = std::sqrt(kLambda * (1 - kLambda) / kN);
  std::vector<double> fractions;
  for (const double f : {0.5, 0.2, 0.1}) {
    const Outcome o = settle(plateScene(f, -1.0));
    const double frac = o.attached / double(kN);
    fractions.push_back(frac);
    std::printf("release one radius, step %.1f radii: %.3f arrivals per particle, attached %.3f (lambda %.2f, 4 SE %.3f)\n", f, o.arrivals, frac,
                kLambda, 4 * se);
    EXPECT_NEAR(o.arrivals, 1.0, 0.01) << "step fraction " << f;
    EXPECT_NEAR(frac, kLambda, 4 * se) << "step fraction " << f;
  }
  EXPECT_NEAR(fractions[0], fractions[2], se);
  EXPECT_NEAR(fractions[1], fractions[2], se);
}

TEST(ArrivalConvergence, FormerRuleMultipliesArrivalsWithRefinement) {
  const double se = std::sqrt(kLambda * (1 - kLambda) / kN);
  std::vector<Outcome> out;
  for (const double f : {0.5, 0.1}) {
    SceneConfig c = plateScene(f, 0.0);  // released as soon as it leaves the capture distance
    out.push_back(settle(c));
    std::printf("former rule, step %.1f radii: %.2f arrivals per particle, attached %.3f\n", f, out.back().arrivals, out.back().attached / double(kN));
  }
  EXPECT_GT(out[1].arrivals, 1.5 * out[0].arrivals);
  EXPECT_GT(out[1].attached / double(kN), kLambda + 4 * se);
}

/// Neutrally buoyant particles (no settling: diffusion alone, with wall hindrance) in a slit 4 radii
/// deep, released at mid-depth, sticky bottom plate; the state after `t_end`.
Outcome diffuse(double step_fraction, double release_distance, double t_end) {
  SceneConfig c = plateScene(step_fraction, release_distance);
  c.particle.density = c.fluid.density;
  c.attachment.favourable_fraction = 0.3;
  const double a = c.particle.radius(), h = 4 * a;
  OverdampedEngine e(std::make_shared<UniformFlow>(Vec2(0, 0), h), c);
  std::vector<Vec3> xs;
  for (int k = 0; k < kN; ++k) xs.emplace_back((k % kSide) * 20e-6, (k / kSide) * 20e-6, h / 2);
  return outcome(e, xs, t_end);
}

// Several arrivals per particle: diffusion between the plate and the release distance (a radius,
// the slit's mid-plane) repeats, lambda = 0.3. With the release distance the attached fraction
// after 1500 s at max_step_fraction 0.5 and 0.2 agrees with 0.1 within 3 standard errors of the
// difference (binomial, sqrt(2 p (1 - p) / n) = 0.035); the steps' Brownian paths differ, so this
// is statistical. Measured (seed 11): 0.360 / 0.412 / 0.425 attached, 1.39 / 1.57 / 1.71 arrivals
// per particle: a residual trend of the diffusion itself (a 1.25 um rms step at 0.5 radii against a
// 5 um gap range), shrinking like the square root of the step; the former rule: 2.16 -> 5.22
// arrivals and 0.555 -> 0.807 attached from 0.5 to 0.1 radii.
TEST(ArrivalConvergence, RepeatedArrivalsConvergeWithTheStep) {
  std::vector<double> fr;
  for (const double f : {0.5, 0.2, 0.1}) {
    const Outcome o = diffuse(f, -1.0, 1500.0);
    fr.push_back(o.attached / double(kN));
    std::printf("diffusing, release one radius, step %.1f radii: %.3f arrivals per particle, attached %.3f\n", f, o.arrivals, fr.back());
  }
  std::vector<Outcome> former;
  for (const double f : {0.5, 0.1}) {
    former.push_back(diffuse(f, 0.0, 1500.0));
    const Outcome& o = former.back();
    std::printf("diffusing, former rule, step %.1f radii: %.3f arrivals per particle, attached %.3f\n", f, o.arrivals, o.attached / double(kN));
  }
  const double se = std::sqrt(2 * fr[2] * (1 - fr[2]) / kN);
  EXPECT_NEAR(fr[0], fr[2], 3 * se);
  EXPECT_NEAR(fr[1], fr[2], 3 * se);
  // The former rule's arrivals more than double from 0.5 to 0.1 radii (near the plate dt falls ~5x:
  // crossings x sqrt(5)), and its attached fraction moves by far more than 3 SE.
  EXPECT_GT(former[1].arrivals, 2 * former[0].arrivals);
  EXPECT_GT(former[1].attached - former[0].attached, 3 * se * kN);
}

}  // namespace
}  // namespace mmval::particles
