// Per-particle steps of the overdamped engine (numerics.substeps; OverdampedEngine.hpp,
// "Substeps"). References: the exact paths of a flow in which every particle keeps its own
// speed, the same engine with one step for all (numerics.substeps = 1), and the hard-sphere
// condition that no particle passes through another.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "mmval/core/Case.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/particles/OverdampedEngine.hpp"
#include "ParticleRegistry.hpp"

namespace mmval::particles {
namespace {

constexpr double kDiameter = 5e-6, kA = 0.5 * kDiameter, kDepth = 20e-6;

/// Plane flow along +x whose speed depends on y only: u = u0 + s y, a tenth of that below
/// y = slow_below. No walls within the bounds; the plates at z = 0 and h.
class StreakFlow final : public FlowField {
 public:
  StreakFlow(double u0, double shear, double slow_below) : m_u0(u0), m_s(shear), m_slow(slow_below) {}
  Vec2 meanVelocity(double, double y) const override { return {(m_u0 + m_s * y) * (y < m_slow ? 0.1 : 1.0), 0.0}; }
  double depth(double, double) const override { return kDepth; }
  bool isSolid(double, double) const override { return false; }
  double wallDistance(double, double) const override { return 1e300; }
  std::uint64_t version() const override { return 1; }
  Bounds2 bounds() const override { return {0, 10e-3, 0, 1e-3}; }

 private:
  double m_u0, m_s, m_slow;
};

/// Plane flow (U, -U / 10) onto a flat grain wall at y = 0 (solid below).
class OntoWall final : public FlowField {
 public:
  explicit OntoWall(double u) : m_u(u) {}
  Vec2 meanVelocity(double, double y) const override { return y < 0 ? Vec2(0, 0) : Vec2(m_u, -0.1 * m_u); }
  double depth(double, double) const override { return kDepth; }
  bool isSolid(double, double y) const override { return y < 0; }
  double wallDistance(double, double y) const override { return std::max(0.0, y); }
  Vec2 wallNormal(double, double) const override { return {0, 1}; }
  std::uint64_t version() const override { return 1; }
  Bounds2 bounds() const override { return {0, 10e-3, -1e-3, 1e-3}; }

 private:
  double m_u;
};

SceneConfig plane(int substeps) {
  SceneConfig c;
  c.particle.diameter = kDiameter;
  c.particle.density = 1000;  // neutrally buoyant in water
  c.gravity = 0;
  c.brownian = false;
  c.depth_profile = false;  // every particle moves with the depth-averaged flow at its (x, y)
  c.wall_hindrance = false;
  c.max_step_fraction = 0.5;
  c.substeps = substeps;
  return c;
}

// A shear u = u0 + s y: each particle keeps its speed, so its path is x0 + u(y0) t at any step. The
// fastest particle (y 0.9 mm, 1 mm/s) is 10x the slowest (0.1 mm/s). With 8 substeps the engine
// takes 8x fewer steps, the particles 1.7x fewer in all (the slow ones one step each per engine
// step, the fast ones up to 8), and every particle is where the exact path puts it (to round-off,
// 1e-12 of its travel); the same with one step for all.
TEST(Substeps, EveryParticleFollowsItsOwnPathWithFewerSteps) {
  auto flow = std::make_shared<StreakFlow>(0.0, 1.0, -1.0);  // u = y (1/s): 0.1-0.9 mm/s
  std::vector<Vec3> starts;
  for (int k = 1; k <= 9; ++k) starts.emplace_back(1e-3, k * 1e-4, 0.5 * kDepth);
  const double t_end = 2.0;
  EngineStats stats[2];
  for (const int K : {1, 8}) {
    OverdampedEngine e(flow, plane(K));
    e.insert(starts);
    e.advance(t_end);
    const auto ps = e.particles();
    for (std::size_t k = 0; k < starts.size(); ++k) {
      const double travel = starts[k].y() * t_end;
      EXPECT_NEAR(ps[k].x.x(), starts[k].x() + travel, 1e-12 * travel) << "K " << K << ", particle " << k;
      EXPECT_EQ(ps[k].x.y(), starts[k].y());
    }
    stats[K == 8] = e.stats();
  }
  // One step for all: the fastest (0.9 mm/s) moves 0.5 a = 1.25 um per step, 1.39 ms: 1440 steps
  // for 2 s, each of them for all 9 particles.
  EXPECT_NEAR(static_cast<double>(stats[0].steps), t_end / (0.5 * kA / 0.9e-3), 2);
  EXPECT_EQ(stats[0].particle_steps, 9 * stats[0].steps);
  EXPECT_NEAR(static_cast<double>(stats[1].steps), stats[0].steps / 8.0, 2);
  // Substeps per engine step: the ceiling of u / (0.9 mm/s / 8), up to 8 -> 1, 2, 3, 4, 5, 6, 7, 8, 8
  // (44 particle steps per engine step; rounded up to powers of 2, as before 2026-12-07: 51).
  EXPECT_EQ(stats[1].particle_steps, (1 + 2 + 3 + 4 + 5 + 6 + 7 + 8 + 8) * stats[1].steps);
}

// A fast particle (1 mm/s) runs head-on into a slow one (0.1 mm/s: the lane below y = 0.5 mm)
// 2 nm off its line, starting 1.1 diameters behind it: with 8 substeps it would move 4 radii in the
// first engine step, to 1.4 radii beyond the slow one's centre, and the contact sweep would push it
// out ahead (checked: without meetsNeighbour the first output, 20 ms, finds it 14 um ahead, 3 nm off
// the line). It stops where it meets the other, the contact sweeps push the two apart, and it can
// only pass by going round: whenever it is ahead, the two are a diameter apart across the lanes.
// A particle following another at the same speed (1 mm/s, 1.1 diameters apart) takes all its
// substeps (its neighbour's place is predicted along its drift).
TEST(Substeps, NoParticlePassesThroughAnother) {
  auto flow = std::make_shared<StreakFlow>(1e-3, 0.0, 0.5e-3);
  OverdampedEngine e(flow, plane(8));
  const double y = 0.5e-3, x0 = 1e-3;
  e.insert({Vec3(x0, y + 1e-9, 0.5 * kDepth), Vec3(x0 + 2.2 * kA, y - 1e-9, 0.5 * kDepth)});
  double closest = 1;
  for (int out = 1; out <= 40; ++out) {
    e.advance(out * 20e-3);  // two engine steps of 10 ms (8 substeps of the fast one's 1.25 ms)
    const auto ps = e.particles();
    const Vec3 gap = ps[1].x - ps[0].x;
    if (gap.x() < 0) {
      EXPECT_GE(std::abs(gap.y()), 2 * kA * (1 - 2e-3)) << "t " << e.time() << ": ahead by " << -gap.x() << " m, " << gap.y() << " m across";
    }
    closest = std::min(closest, gap.norm());
  }
  EXPECT_GE(closest, 2 * kA * (1 - 2e-3));

  auto plug = std::make_shared<StreakFlow>(1e-3, 0.0, -1.0);
  OverdampedEngine train(plug, plane(8));
  train.insert({Vec3(x0, y, 0.5 * kDepth), Vec3(x0 + 2.2 * kA, y, 0.5 * kDepth)});
  train.advance(0.1);
  EXPECT_EQ(train.stats().particle_steps, 2 * 8 * train.stats().steps);
  EXPECT_NEAR(train.particles()[0].x.x(), x0 + 1e-4, 1e-15);
}

// A particle pressed onto a grain wall slides along it: with 8 substeps it takes all 8 in every
// engine step and goes as far as with one step for all, U t (the wall step is exact on a flat
// wall). With the first rule, which stopped a particle at every grain contact for the rest of the
// engine step, it went 1/8 as far (the test fails), and every particle sliding along a grain moved
// 8x slower than its flow.
TEST(Substeps, AParticleSlidesAlongAGrainWallThroughItsSubsteps) {
  auto flow = std::make_shared<OntoWall>(1e-3);
  SceneConfig c = plane(8);
  c.attachment.grains = false;
  double travel[2] = {0, 0};
  for (const int K : {1, 8}) {
    c.substeps = K;
    OverdampedEngine e(flow, c);
    e.insert({Vec3(1e-3, kA, 0.5 * kDepth)});
    e.advance(0.1);
    ASSERT_EQ(e.particles()[0].status, ParticleStatus::mobile);
    EXPECT_NEAR(e.particles()[0].x.y(), kA, 1e-3 * kA);
    travel[K == 8] = e.particles()[0].x.x() - 1e-3;
    if (K == 8) {
      EXPECT_GE(e.stats().particle_steps, 8 * (e.stats().steps - 1));  // the last step ends at 0.1 s
    }
  }
  EXPECT_NEAR(travel[0], 1e-4, 1e-12);
  EXPECT_NEAR(travel[1], travel[0], 1e-12);
}

TEST(Substeps, ACountThatIsNotAPowerOfTwoIsAnInputErrorNamingTheKey) {
  auto flow = std::make_shared<StreakFlow>(1e-3, 0.0, -1.0);
  for (const int bad : {0, 3, 128}) {
    try {
      const OverdampedEngine e(flow, plane(bad));
      ADD_FAILURE() << "substeps " << bad << " accepted";
    } catch (const InputError& err) {
      EXPECT_EQ(err.where().key, "numerics.substeps");
    }
  }
  // In a case file, out of range or not an integer (3 passes the file's range and is refused where
  // the run reads it, by the same check as the engine's).
  for (const char* value : {"0", "128", "\"four\""}) {
    const std::string text = std::string("[case]\nname = \"t\"\nkind = \"particles-channel\"\n[numerics]\nsubsteps = ") + value + "\n";
    try {
      (void)Case::parse(text, "cases/substeps-test.toml", test_support::particleRegistry());
      ADD_FAILURE() << "numerics.substeps = " << value << " accepted";
    } catch (const InputError& err) {
      EXPECT_EQ(err.where().key, "numerics.substeps") << value;
    }
  }
}

}  // namespace
}  // namespace mmval::particles
