// The overdamped engine against exact answers (settling, Poiseuille advection,
// wall factors), statistics (MSD vs Stokes-Einstein) and self-consistency
// (particle counts balance, determinism, insertion checks).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <iostream>

#include "mmval/core/Error.hpp"
#include "mmval/particles/OverdampedEngine.hpp"

namespace mmval::particles {
namespace {

SceneConfig still() {
  SceneConfig c;
  c.brownian = false;
  c.wall_hindrance = false;
  c.faxen_curvature = false;
  c.gravity = 0;
  c.attachment.capture_distance = 0;
  return c;
}

// Free Stokes settling of 5 um polystyrene through 20 um: 28 s (Stokes' law, v = 2 drho g a^2 / (9 mu),
// 2 digits: +-0.5 s). The capture time resolves it to one step (0.01 a / v_s = 0.035 s).
TEST(Overdamped, SettlesThrough20umInStokesTime) {
  SceneConfig c = still();
  c.gravity = 9.81;
  c.attachment.capture_distance = 1e-12;
  c.attachment.grains = false;
  c.max_step_fraction = 0.01;
  const double a = c.particle.radius(), h = 20e-6 + 2 * a;
  auto flow = std::make_shared<UniformFlow>(Vec2(0, 0), h);
  OverdampedEngine e(flow, c);
  e.insert({Vec3(0, 0, h - a)});
  EXPECT_NEAR(e.driftVelocity(Vec3(0, 0, 0.5 * h)).z(), -settlingSpeed(c.fluid, c.particle), 1e-12 * 7e-7);
  e.advance(40.0);
  const auto p = e.particles()[0];
  ASSERT_EQ(p.status, ParticleStatus::deposited);
  EXPECT_NEAR(p.t_event, 28.0, 0.5);
  EXPECT_NEAR(p.t_event, 20e-6 / settlingSpeed(c.fluid, c.particle), 0.04);
}

// With the plates' Brenner correction the fall is slower: t = int lambda_perp(z) dz / v_s.
// Reference by the midpoint rule on 20000 intervals of the same hindrance function;
// the engine integrates it with steps of 0.01 a, so 1 % is its discretisation error.
TEST(Overdamped, HinderedSettlingFollowsBrennerIntegral) {
  SceneConfig c = still();
  c.gravity = 9.81;
  c.wall_hindrance = true;
  c.attachment.capture_distance = 0.05e-6;
  c.attachment.grains = false;
  c.max_step_fraction = 0.01;
  const double a = c.particle.radius(), h = 20e-6 + 2 * a;
  auto flow = std::make_shared<UniformFlow>(Vec2(0, 0), h);
  OverdampedEngine e(flow, c);
  const double z0 = h - a - 1e-6, z1 = a + c.attachment.capture_distance;
  e.insert({Vec3(0, 0, z0)});
  double t_ref = 0;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    const double z = z1 + (i + 0.5) * (z0 - z1) / n;
    t_ref += e.model().hindrance(z, h).second * (z0 - z1) / n / settlingSpeed(c.fluid, c.particle);
  }
  e.advance(3 * t_ref);
  const auto p = e.particles()[0];
  ASSERT_EQ(p.status, ParticleStatus::deposited);
  std::cout << "hindered settling: engine " << p.t_event << " s, integral " << t_ref << " s\n";
  EXPECT_NEAR(p.t_event, t_ref, 0.01 * t_ref) << "free fall would take " << (z0 - z1) / settlingSpeed(c.fluid, c.particle) << " s";
  EXPECT_GT(t_ref, 1.2 * (z0 - z1) / settlingSpeed(c.fluid, c.particle));
}

// The hindrance the engine uses reproduces the tabulated single-wall factors
// (other plate far away): table interpolation error < 1e-3. Parallel factors at gaps >= a,
// where the near-contact join is Faxen's series itself.
TEST(Overdamped, WallFactorsMatchFaxenAndBrenner) {
  SceneConfig c = still();
  c.wall_hindrance = true;
  const double a = c.particle.radius(), far = 1.0;
  auto flow = std::make_shared<UniformFlow>(Vec2(0, 0), far);
  OverdampedEngine e(flow, c);
  const auto at = [&](double centre) { return e.model().hindrance(centre, far); };
  EXPECT_NEAR(at(10 * a).first, 1.060, 2e-3);   // Faxen x = 0.1 (+ far plate ~1e-6)
  EXPECT_NEAR(at(5 * a).first, 1.126, 2e-3);    // x = 0.2
  EXPECT_NEAR(at(2 * a).first, 1.386, 2e-3);    // x = 0.5
  EXPECT_NEAR(at(1.1 * a).second, 11.46, 0.01 * 11.46);
  EXPECT_NEAR(at(2 * a).second, 2.126, 1e-3 * 2.126);
  EXPECT_NEAR(at(10 * a).second, 1.126, 1e-3 * 1.126);
}

// Free Brownian particles: MSD in the plane = 4 D t. With N particles the MSD
// estimate has standard error 4 D t / sqrt(N) (r^2 = 2 D t chi^2_2); the test
// allows 2 standard errors, seed fixed.
TEST(Overdamped, MeanSquareDisplacementIsFourDt) {
  SceneConfig c = still();
  c.brownian = true;
  c.seed = 20240611;
  auto flow = std::make_shared<UniformFlow>(Vec2(0, 0), 1.0, Bounds2{-1, 1, -1, 1});
  OverdampedEngine e(flow, c);
  std::vector<Vec3> start;
  for (int i = 0; i < 40; ++i)
    for (int j = 0; j < 50; ++j) start.emplace_back(i * 50e-6, j * 50e-6, 0.5);
  e.insert(start);
  const double t = 10.0, D = stokesEinstein(c.fluid, c.particle.diameter);
  e.advance(t);
  const auto ps = e.particles();
  double msd = 0;
  for (std::size_t k = 0; k < ps.size(); ++k) msd += (ps[k].x - start[k]).head<2>().squaredNorm();
  msd /= ps.size();
  const double ref = 4 * D * t, se = ref / std::sqrt(static_cast<double>(ps.size()));
  EXPECT_NEAR(msd, ref, 2 * se) << "MSD " << msd << " m2 vs 4Dt " << ref << " m2, 2 SE = " << 2 * se;
  EXPECT_GE(e.stats().steps, 20);  // Brownian step (0.1 a)^2 / (2 D) = 0.36 s
}

// A particle in the Hele-Shaw profile moves at u(z) = 6 U z (h - z) / h^2
// (+ Faxen's -2 U a^2 / h^2 when on, + with wall hydrodynamics on the plates' shear lag
// U slitShearLag, whose values Physics.FreeSphereInShear* check against Goldman, Cox &
// Brenner); deterministic, so round-off tolerance.
TEST(Overdamped, PoiseuilleParticleFollowsAnalyticVelocity) {
  for (int variant = 0; variant < 3; ++variant) {
    const bool faxen = variant > 0;
    SceneConfig c = still();
    c.faxen_curvature = faxen;
    c.wall_hindrance = variant == 2;
    const double U = 7e-4, h = 20e-6, a = c.particle.radius();
    auto flow = std::make_shared<HeleShawChannel>(1.0, 1e-3, h, U);
    OverdampedEngine e(flow, c);
    EXPECT_EQ(e.model().nearWallShear(), variant == 2);  // on by default, off without wall hydrodynamics
    const std::vector<double> zs = {a, 5e-6, 10e-6, 14e-6, h - a};
    std::vector<Vec3> start;
    for (std::size_t k = 0; k < zs.size(); ++k) start.emplace_back(1e-4, 1e-4 + 100e-6 * k, zs[k]);
    e.insert(start);
    e.advance(0.5);
    const auto ps = e.particles();
    for (std::size_t k = 0; k < zs.size(); ++k) {
      const double z = zs[k];
      const double lag = e.model().nearWallShear() ? slitShearLag(a, z, h) : 0.0;
      const double u = U * (6 * z * (h - z) / (h * h) - (faxen ? 2 * a * a / (h * h) : 0.0) + lag);
      EXPECT_NEAR((ps[k].x.x() - start[k].x()) / 0.5, u, 1e-9 * U) << "z = " << z << " variant " << variant;
      EXPECT_NEAR(ps[k].x.z(), z, 1e-15);
    }
  }
}

// Near the bottom plate of a deep chip (h = 1e4 a, so the profile is the wall shear
// gamma z to 1e-3) a free sphere lags the fluid as Goldman, Cox & Brenner's table says:
// U/(gamma z) = 0.4529 at h/a = 1.003202 and 0.7669 at 1.1276 (reference-data/
// goldman-cox-brenner.toml); the model is within 0.4 % there, the curvature 0.1 %: 1 %.
TEST(Overdamped, FreeSphereNearPlateLagsAsGoldmanCoxBrenner) {
  SceneConfig c = still();
  c.wall_hindrance = true;
  c.faxen_curvature = true;
  const double a = c.particle.radius(), h = 1e4 * a, gamma = 100.0;
  auto flow = std::make_shared<UniformFlow>(Vec2(gamma * h / 6, 0), h);
  OverdampedEngine e(flow, c);
  if (!e.model().nearWallShear()) GTEST_SKIP() << "near-wall shear switched off";
  for (const auto& [s, ref] : {std::pair{1.003202, 0.4529}, std::pair{1.1276, 0.7669}})
    EXPECT_NEAR(e.driftVelocity(Vec3(0, 0, s * a)).x() / (gamma * s * a), ref, 0.01 * ref) << "h/a = " << s;
}

// The Ito drift comes from the normal mobility only: no forces, no flow, Brownian on:
// the drift is k_B T d(1/(6 pi mu a lambda_perp))/dz along z and nothing in the plane (the
// parallel mobility depends on z, not on x or y). lambda_perp from Brenner's exact series
// on both plates. The engine differentiates its log-linear table of lambda_perp (801 nodes
// over 8 decades of gap) across 1e-3 a, i.e. within one table interval, so its slope is
// the interval's chord slope: first-order error, measured 0.25 % at z = 1.2 a; 1 %.
TEST(Overdamped, ItoDriftComesFromTheNormalMobilityOnly) {
  SceneConfig c = still();
  c.brownian = true;
  c.wall_hindrance = true;
  const double a = c.particle.radius(), h = 20e-6;
  auto flow = std::make_shared<UniformFlow>(Vec2(0, 0), h);
  OverdampedEngine e(flow, c);
  const double D = stokesEinstein(c.fluid, c.particle.diameter);
  for (const double z : {1.2 * a, 1.6 * a, 0.5 * h}) {
    const Vec3 v = e.driftVelocity(Vec3(0, 0, z));
    const double dz = 1e-3 * a;
    const auto inv = [&](double zz) { return 1.0 / twoWallPerpendicular(a, zz, h); };
    const double ref = D * (inv(z + dz) - inv(z - dz)) / (2 * dz);
    EXPECT_EQ(v.x(), 0.0);
    EXPECT_EQ(v.y(), 0.0);
    EXPECT_NEAR(v.z(), ref, 1e-2 * std::abs(ref) + 1e-9 * D / a) << "z/a = " << z / a;
  }
}

// With SceneConfig::near_wall_shear and near_contact_drag off the engine is the former
// one: fluid velocity at the centre and Faxen's parallel series.
template <class C>
bool switchOffNearWallTerms(C& c) {
  if constexpr (requires { c.near_wall_shear; c.near_contact_drag; }) {
    c.near_wall_shear = false;
    c.near_contact_drag = false;
    return true;
  } else {
    return false;
  }
}
TEST(Overdamped, NearWallTermsSwitchOff) {
  SceneConfig c = still();
  c.wall_hindrance = true;
  if (!switchOffNearWallTerms(c)) GTEST_SKIP() << "SceneConfig has no near_wall_shear / near_contact_drag switches";
  const double a = c.particle.radius(), h = 20e-6;
  auto flow = std::make_shared<HeleShawChannel>(1.0, 1e-3, h, 7e-4);
  OverdampedEngine e(flow, c);
  const Vec3 x(1e-4, 1e-4, 1.05 * a);
  EXPECT_EQ(e.model().shearLag(x), Vec3::Zero());
  EXPECT_NEAR(e.driftVelocity(x).x(), e.model().fluidVelocity(x).x(), 1e-15);
  EXPECT_NEAR(e.model().hindrance(1.05 * a, h).first, twoWallParallel(a, 1.05 * a, h), 1e-12);
}

// Mass conservation of particle counts in a sticky channel with an outlet:
// injected == inside + deposited + left after every interval, and all three
// sinks are exercised.
TEST(Overdamped, ParticleCountsBalanceWithDepositionAndOutlet) {
  SceneConfig c;
  c.seed = 5;
  c.gravity = 9.81 * 20;  // some settle within the short channel, others leave
  const double L = 300e-6, W = 100e-6, h = 20e-6;
  auto flow = std::make_shared<HeleShawChannel>(L, W, h, 7e-4);
  OverdampedEngine e(flow, c);
  std::int64_t injected = 0;
  for (int k = 1; k <= 20; ++k) {
    const auto pos = sampleInlet(*flow, c.particle.radius(), 0.0, 20e-6, 5, 1000 + k, e.particles());
    e.insert(pos);
    injected += 5;
    e.advance(k * 0.05);
    const Counts n = e.counts();
    ASSERT_TRUE(n.balanced()) << n.injected << " != " << n.inside << " + " << n.deposited << " + " << n.left;
    ASSERT_EQ(n.injected, injected);
  }
  e.advance(3.0);
  const Counts n = e.counts();
  EXPECT_TRUE(n.balanced());
  EXPECT_GT(n.deposited, 0);
  EXPECT_GT(n.left, 0);
  for (const auto& p : e.particles()) {
    if (p.status == ParticleStatus::left) continue;
    EXPECT_GE(p.x.z(), c.particle.radius() - 1e-15);
    EXPECT_LE(p.x.z(), h - c.particle.radius() + 1e-15);
  }
}

TEST(Overdamped, SameSeedSameTrajectories) {
  SceneConfig c;
  c.seed = 11;
  auto flow = std::make_shared<HeleShawChannel>(300e-6, 100e-6, 20e-6, 7e-4);
  const auto run = [&] {
    OverdampedEngine e(flow, c);
    e.insert(sampleInlet(*flow, c.particle.radius(), 0.0, 50e-6, 20, 3, {}));
    e.advance(0.2);
    return e.particles();
  };
  const auto a = run(), b = run();
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) EXPECT_EQ((a[k].x - b[k].x).norm(), 0.0);
}

TEST(Overdamped, InsertionIntoSolidOrOverlapIsAClearError) {
  SceneConfig c;
  auto flow = std::make_shared<HeleShawChannel>(300e-6, 100e-6, 20e-6, 7e-4);
  OverdampedEngine e(flow, c);
  e.insert({Vec3(50e-6, 50e-6, 10e-6)});
  EXPECT_THROW(e.insert({Vec3(50e-6, -5e-6, 10e-6)}), InputError);     // in a side wall
  EXPECT_THROW(e.insert({Vec3(52e-6, 50e-6, 10e-6)}), InputError);     // overlaps particle 1
  EXPECT_THROW(e.insert({Vec3(80e-6, 50e-6, 1e-6)}), InputError);      // crosses the bottom plate
  try {
    e.insert({Vec3(52e-6, 50e-6, 10e-6)});
  } catch (const InputError& err) {
    EXPECT_NE(std::string(err.what()).find("overlaps particle 1"), std::string::npos) << err.what();
  }
  EXPECT_EQ(e.counts().injected, 1);
  // Particles larger than the depth cannot be placed anywhere.
  EXPECT_THROW(sampleInlet(HeleShawChannel(300e-6, 100e-6, 4e-6, 7e-4), 2.5e-6, 0.0, 20e-6, 1, 1, {}), InputError);
}

// Hard contacts: a particle advected onto a deposited one stops there (ripening)
// and no pair ends up overlapping.
TEST(Overdamped, ContactWithDepositedParticleAttachesWithoutOverlap) {
  SceneConfig c = still();
  c.attachment.capture_distance = 0.1e-6;
  c.attachment.grains = false;
  const double a = c.particle.radius();
  auto flow = std::make_shared<HeleShawChannel>(300e-6, 100e-6, 20e-6, 7e-4);
  OverdampedEngine e(flow, c);
  e.insert({Vec3(100e-6, 50e-6, a), Vec3(80e-6, 50e-6, a + 1e-6)});
  e.advance(0.001);
  ASSERT_EQ(e.particles()[0].status, ParticleStatus::deposited);
  e.advance(0.5);
  const auto ps = e.particles();
  EXPECT_EQ(ps[1].status, ParticleStatus::deposited);
  EXPECT_GE((ps[0].x - ps[1].x).norm(), 2 * a * (1 - 1e-9));
}

}  // namespace
}  // namespace mmval::particles

namespace mmval::particles {
namespace {

// Attachment efficiency alpha on the plate: 400 particles settle onto the sticky bottom in still
// fluid; each arrival attaches with probability alpha, so the attached count is binomial
// (400, alpha): 2 standard errors (0.05 at alpha = 0.5) bound it (seed 7: 194 of 400). The rejected ones stay mobile
// on the plate, and the same seed draws the same particles.
std::vector<ParticleState> settleMany(double alpha, std::uint64_t seed) {
  SceneConfig c = still();
  c.gravity = 9.81;
  c.attachment.capture_distance = 0.05e-6;
  c.attachment.grains = false;
  c.attachment.deposited = false;
  c.attachment.plate_efficiency = alpha;
  c.seed = seed;
  const double a = c.particle.radius(), h = 20e-6 + 2 * a;
  auto flow = std::make_shared<UniformFlow>(Vec2(0, 0), h);
  OverdampedEngine e(flow, c);
  std::vector<Vec3> xs;
  for (int i = 0; i < 20; ++i)
    for (int j = 0; j < 20; ++j) xs.emplace_back(i * 20e-6, j * 20e-6, h - a - 1e-6);
  e.insert(xs);
  e.advance(40.0);  // 28 s to settle 20 um
  return e.particles();
}

TEST(Overdamped, PlateAttachmentEfficiencyIsTheFractionOfArrivalsThatStick) {
  for (double alpha : {0.0, 0.5, 1.0}) {
    const auto ps = settleMany(alpha, 7);
    const double a = still().particle.radius();
    int stuck = 0, on_plate = 0;
    for (const auto& p : ps) {
      stuck += p.status == ParticleStatus::deposited ? 1 : 0;
      on_plate += (p.status == ParticleStatus::mobile && p.x.z() < a + 0.05e-6 && p.plate_rejected) ? 1 : 0;
    }
    std::printf("alpha %.2f: %d of 400 attached\n", alpha, stuck);
    EXPECT_NEAR(stuck / 400.0, alpha, 0.05) << "alpha " << alpha;
    EXPECT_EQ(stuck + on_plate, 400) << "every particle arrived once; the rejected ones wait on the plate";
  }
  const auto a = settleMany(0.5, 7), b = settleMany(0.5, 7), c = settleMany(0.5, 8);
  int same = 0, differ = 0;
  for (std::size_t k = 0; k < a.size(); ++k) {
    same += a[k].status == b[k].status ? 1 : 0;
    differ += a[k].status != c[k].status ? 1 : 0;
  }
  EXPECT_EQ(same, 400);
  EXPECT_GT(differ, 100) << "another seed draws other particles";
}

}  // namespace
}  // namespace mmval::particles

namespace mmval::particles {
namespace {

// Attachment is decided after the contacts of a step are resolved: in a dense deposit (~670
// particles raining onto a sticky bottom plate and side walls, with Brownian motion, so that
// particles land next to and onto deposits) no two deposited particles overlap. Before the fix a
// particle that reached the plate attached in the same step it was pushed into a deposit and was
// never separated (overlaps of up to ~0.2 radii). Tolerance 1e-3 radii: the contact sweeps stop
// after 4 passes, and 1e-3 a (2.5 nm) is far below any length the deposit geometry resolves.
TEST(Overdamped, DenseDepositHasNoOverlaps) {
  SceneConfig c;
  c.seed = 3;
  c.gravity = 9.81 * 30;  // settle 20 um in ~1 s instead of 28 s
  c.attachment.capture_distance = 0.1e-6;
  const double a = c.particle.radius(), h = 20e-6;
  auto flow = std::make_shared<HeleShawChannel>(120e-6, 60e-6, h, 0.0);
  OverdampedEngine e(flow, c);
  // Layers of 171 particles just below the top plate, each shifted in the plane, dropped
  // every 0.5 s; settling at 30 g takes ~0.7 s, so layers rain onto a growing deposit.
  for (int layer = 0; layer < 8; ++layer) {
    std::vector<Vec3> xs;
    const double sx = 0.37e-6 * ((layer * 7) % 8), sy = 0.41e-6 * ((layer * 3) % 8);
    for (int i = 0; i < 19; ++i)
      for (int j = 0; j < 9; ++j) {
        const Vec3 x(3.0e-6 + i * 6.1e-6 + sx, 3.0e-6 + j * 6.1e-6 + sy, h - a - 0.2e-6);
        if (insertionProblem(*flow, a, x, e.particles()).empty()) xs.push_back(x);
      }
    e.insert(xs);
    e.advance(0.5 * (layer + 1));
  }
  e.advance(8.0);
  std::vector<ParticleState> dep;
  for (const auto& p : e.particles())
    if (p.status == ParticleStatus::deposited) dep.push_back(p);
  const Counts n = e.counts();
  std::printf("dense deposit: %lld injected, %lld deposited, %lld inside, %lld left\n", static_cast<long long>(n.injected),
              static_cast<long long>(n.deposited), static_cast<long long>(n.inside), static_cast<long long>(n.left));
  ASSERT_GT(dep.size(), 600u);
  double worst = 0;
  int overlapping = 0;
  for (std::size_t i = 0; i < dep.size(); ++i)
    for (std::size_t j = i + 1; j < dep.size(); ++j) {
      const double overlap = 2 * a - (dep[i].x - dep[j].x).norm();
      worst = std::max(worst, overlap);
      overlapping += overlap > 1e-3 * a ? 1 : 0;
    }
  std::printf("dense deposit: %zu deposited, worst overlap %.3g radii, %d pairs over 1e-3 a\n", dep.size(), worst / a, overlapping);
  EXPECT_EQ(overlapping, 0) << "worst overlap " << worst / a << " radii";
}

// physics.ito_drift off removes exactly the Ito term: the drift then is the deterministic
// velocity alone, and on it is k_B T d(1/lambda_perp)/dz / (6 pi mu a) (a central difference
// of the same hindrance function; 1e-6 relative: the difference's truncation error).
TEST(Overdamped, ItoDriftSwitchesOff) {
  SceneConfig c = still();
  c.brownian = true;
  c.wall_hindrance = true;
  const double a = c.particle.radius(), h = 20e-6;
  auto flow = std::make_shared<UniformFlow>(Vec2(0, 0), h);
  OverdampedEngine on(flow, c);
  c.ito_drift = false;
  OverdampedEngine off(flow, c);
  const double z = a + 0.3e-6, e = 1e-3 * a;  // the engine's difference step
  const double ref = on.model().diffusivity() * (1 / on.model().normalHindrance(z + e, h) - 1 / on.model().normalHindrance(z - e, h)) / (2 * e);
  EXPECT_EQ(off.driftVelocity(Vec3(0, 0, z)).z(), 0.0);
  std::printf("Ito drift at gap 0.3 um: %.6g m/s (central difference %.6g)\n", on.driftVelocity(Vec3(0, 0, z)).z(), ref);
  EXPECT_NEAR(on.driftVelocity(Vec3(0, 0, z)).z(), ref, 1e-9 * std::abs(ref));
  EXPECT_GT(ref, 0.0) << "the mobility grows away from the plate";
}

}  // namespace
}  // namespace mmval::particles
