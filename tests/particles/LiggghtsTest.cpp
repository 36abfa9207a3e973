// LIGGGHTS driven in-process, 1 rank (singleton MPI). Each test runs a few
// thousand to ~2e5 DEM steps of one or two particles.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>

#include <iostream>

#include "GridField.hpp"
#include "mmval/particles/EngineComparison.hpp"
#include "mmval/particles/LiggghtsEngine.hpp"
#include "mmval/particles/OverdampedEngine.hpp"

#include "../TestScratch.hpp"

namespace mmval::particles {
namespace {

SceneConfig quietScene(const std::string& name) {
  SceneConfig c;
  c.gravity = 0;
  c.brownian = false;
  c.wall_hindrance = false;
  c.faxen_curvature = false;
  c.attachment.capture_distance = 0;
  c.work_dir = mmval::test::scratch("mmval-liggghts-test-" + name);
  return c;
}

// A sphere released at rest in a uniform flow relaxes as v = U (1 - exp(-t / tau_p)).
// The drag integrator is exact for constant flow, so the tolerance is round-off of
// the ~100 steps plus the half step the run setup adds (O((dt/tau)^2) ~ 1e-3).
TEST(Liggghts, SphereRelaxesToFlowVelocityWithTauP) {
  const double u_mean = 1e-3, h = 100e-6;
  auto flow = std::make_shared<UniformFlow>(Vec2(u_mean, 0), h, Bounds2{0, 200e-6, 0, 100e-6});
  SceneConfig c = quietScene("relax");
  LiggghtsEngine e(flow, c);
  e.insert({Vec3(50e-6, 50e-6, 0.5 * h)});
  const double tau = relaxationTime(c.fluid, c.particle), uf = 1.5 * u_mean;  // centre line of the profile
  ASSERT_GT(tau / e.dt(), 5.0) << "test meant for several steps per tau";
  for (double k : {0.5, 1.0, 2.0, 5.0}) {
    e.advance(k * tau);
    const double t = e.time();
    const double expected = uf * (1 - std::exp(-t / tau));
    const double got = e.particles()[0].v.x();
    EXPECT_NEAR(got, expected, 2e-3 * uf) << "t/tau = " << t / tau << " dt/tau = " << e.dt() / tau;
  }
}

// Stokes settling onto the bottom plate: the speed far from the walls is the
// Stokes speed (wall hindrance off), and the sphere comes to rest on the plate
// with a Hertz overlap of ~1e-9 m. Gravity is raised 100x so that the fall
// takes ~1e5 DEM steps instead of ~1e8.
TEST(Liggghts, SphereSettlesOntoBottomWall) {
  const double h = 40e-6;
  auto flow = std::make_shared<UniformFlow>(Vec2(0, 0), h, Bounds2{0, 60e-6, 0, 60e-6});
  SceneConfig c = quietScene("settle");
  c.gravity = 981;
  c.particle.density = 2000;
  LiggghtsEngine e(flow, c);
  const double a = c.particle.radius(), z0 = a + 10e-6;
  e.insert({Vec3(30e-6, 30e-6, z0)});
  const double vs = settlingSpeed(c.fluid, c.particle, c.gravity);
  e.advance(0.3 * 10e-6 / vs);  // fallen ~3 um, far from either plate (hindrance off anyway)
  const auto p = e.particles()[0];
  EXPECT_NEAR(p.v.z(), -vs, 1e-3 * vs) << "Stokes settling speed " << vs << " m/s";
  EXPECT_NEAR(p.x.z(), z0 - vs * e.time(), 0.01 * 3e-6) << "position after free fall (tau_p transient is 1e-6 s)";
  e.advance(1.5 * 10e-6 / vs);
  const auto q = e.particles()[0];
  EXPECT_NEAR(q.x.z(), a, 1e-8) << "rests on the plate (Hertz overlap ~1e-9 m)";
  EXPECT_LT(std::abs(q.v.z()), 1e-3 * vs);
}

// Hertz head-on collision: two spheres approaching at +-v/2 stay in contact for
// t_c = 2.868 (m*^2 / (R* E*^2 v))^(1/5) (Johnson 1985; reference-data/particle-facts.toml). Nearly elastic, no fluid
// (viscosity 1e-12 Pa s), the contact time measured from the centre distance.
TEST(Liggghts, HeadOnCollisionLastsHertzContactTime) {
  const double h = 100e-6;
  auto flow = std::make_shared<UniformFlow>(Vec2(0, 0), h, Bounds2{0, 100e-6, 0, 60e-6});
  SceneConfig c = quietScene("hertz");
  c.fluid.viscosity = 1e-12;
  c.particle.restitution = 0.99;
  c.rayleigh_fraction = 0.02;  // ~180 steps per contact: the measurement resolves 1 %
  LiggghtsEngine e(flow, c);
  const double d = c.particle.diameter, v = 0.05, gap = 0.01e-6;
  e.insert({Vec3(50e-6 - 0.5 * d - 0.5 * gap, 30e-6, 50e-6), Vec3(50e-6 + 0.5 * d + 0.5 * gap, 30e-6, 50e-6)});
  e.setVelocity(1, Vec3(0.5 * v, 0, 0));
  e.setVelocity(2, Vec3(-0.5 * v, 0, 0));
  const double tc = hertzContactTimeEqual(c.particle, v);
  double t_in = -1, t_out = -1;
  const double dt = e.dt();
  for (int k = 1; k < 4 * static_cast<int>(tc / dt) && t_out < 0; ++k) {
    e.advance(k * dt);
    const auto ps = e.particles();
    const double dist = (ps[0].x - ps[1].x).norm();
    if (t_in < 0 && dist < d) t_in = e.time();
    if (t_in >= 0 && dist >= d) t_out = e.time();
  }
  ASSERT_GT(t_out, 0) << "no separation seen";
  EXPECT_NEAR(t_out - t_in, tc, 0.03 * tc) << "dt = " << dt << " s, t_c = " << tc << " s (restitution 0.99: damping lengthens it < 1 %)";
}

// Paper Eq. 14 at run time: a particle thrown at 5 m/s makes the Hertz time of a
// head-on pair at 10 m/s the binding limit (t_c / 20 below the Rayleigh fraction);
// once water has stopped it (tau_p = 1.5 us), the step returns to the setup's.
TEST(Liggghts, TimeStepFollowsTheFastestParticle) {
  auto flow = std::make_shared<UniformFlow>(Vec2(0, 0), 40e-6, Bounds2{0, 400e-6, 0, 100e-6});
  SceneConfig c = quietScene("retime");
  LiggghtsEngine e(flow, c);
  const double dt0 = e.dt();
  e.insert({Vec3(50e-6, 50e-6, 20e-6)});
  e.setVelocity(1, Vec3(5.0, 0, 0));
  e.advance(2e-8);
  const double hertz = hertzContactTimeEqual(c.particle, 10.0) / 20;
  ASSERT_LT(hertz, dt0) << "the test needs Hertz to bind at 10 m/s";
  EXPECT_NEAR(e.dt(), hertz, 1e-12 * hertz);
  const double t = e.time();
  e.advance(t + 30e-6);  // 20 tau_p: at rest in still water
  EXPECT_LT(e.particles()[0].v.norm(), 1e-6);
  e.advance(e.time() + 1e-6);
  EXPECT_DOUBLE_EQ(e.dt(), dt0);
  EXPECT_NEAR(e.time(), t + 31e-6, 2 * dt0);  // time keeps counting across the changes
  EXPECT_DOUBLE_EQ(e.stats().min_dt, hertz);
  EXPECT_DOUBLE_EQ(e.stats().max_dt, dt0);
}

// The shared window of a scene (compareOnScene): LIGGGHTS runs once for all overdamped
// step settings, particles start clear of grains and of each other, and the engines stay
// within a fraction of a diameter. (This uniform field is not divergence-free around its
// grain: particles are pushed into it, where Hertz contact and the overdamped hard-sphere
// rule differ by ~0.7 um whatever the step; on the micromodel's Stokes flow the error
// falls with the step: cases/particles-micromodel-engines.toml.)
TEST(EngineComparison, SceneWindowRunsLiggghtsOnceForEveryStepSetting) {
  auto flow = test_support::gridField(40, 16, 5e-4, 20e-6, [](int i, int j) { return i >= 20 && i < 24 && j >= 6 && j < 10; });
  SceneConfig c = quietScene("scene-window");
  c.gravity = 9.81;
  c.particle.youngs_modulus = 1e5;
  c.attachment.capture_distance = 0.1e-6;
  SceneWindow w;
  w.window = 0.05;
  w.interval = 0.005;
  w.particles = 12;
  w.gravity_factor = 100;
  std::vector<SceneConfig> candidates(2, c);
  candidates[0].max_step_fraction = 0.5;
  candidates[1].max_step_fraction = 0.05;
  const auto r = compareOnScene(flow, c, w, candidates);
  ASSERT_EQ(r.size(), 2u);
  EXPECT_EQ(r[0].steps_reference, r[1].steps_reference);
  EXPECT_EQ(r[0].particles, 12);
  EXPECT_LT(r[1].steps_candidate, r[0].steps_reference / 10);
  EXPECT_GT(r[1].steps_candidate, 5 * r[0].steps_candidate);
  for (const auto& e : r) {
    EXPECT_LT(e.rms_position_difference, 0.5 * c.particle.diameter);
    EXPECT_LE(std::abs(e.captured_reference - e.captured_candidate), 1);
    EXPECT_EQ(e.reference_version.rfind("LIGGGHTS", 0), 0u) << "the reference's version, for the run's provenance: " << e.reference_version;
  }
  for (const auto& p : samplePoreSpace(*flow, c.particle.radius(), 12, w.seed)) EXPECT_TRUE(insertionProblem(*flow, c.particle.radius(), p, {}).empty());
}

// A grain of a gridded field (here a wall of solid nodes across the channel) is an STL
// mesh wall in LIGGGHTS: a sphere thrown at it (no fluid to speak of: viscosity
// 1e-12 Pa s) touches it at x = face - a, penetrates no more than the Hertz overlap of
// the impact (~0.5 um at 0.05 m/s, E = 1e6 Pa; more than half of it with damping), and leaves with the material's
// coefficient of restitution (LIGGGHTS derives the Hertz damping from it).
TEST(Liggghts, SphereBouncesOffAGridGrainWithItsRestitution) {
  const double dx = 10e-6, h = 20e-6;
  auto flow = test_support::gridField(30, 12, 0.0, h, [](int i, int) { return i >= 22; });
  SceneConfig c = quietScene("grain-bounce");
  c.fluid.viscosity = 1e-12;
  LiggghtsEngine e(flow, c);
  const double a = c.particle.radius(), face = 21.5 * dx, v = 0.05;
  e.insert({Vec3(100e-6, 55e-6, 0.5 * h)});
  e.setVelocity(1, Vec3(v, 0, 0));
  // Coast to just before contact, then follow the contact step by step (~30 DEM steps).
  const double t_hit = (face - a - 100e-6) / v;
  e.advance(t_hit - 2e-6);
  double x_max = 0;
  for (int k = 1; k <= 200; ++k) {
    e.advance(e.time() + e.dt());
    x_max = std::max(x_max, e.particles()[0].x.x());
  }
  e.advance(1.5 * t_hit);
  // Hertz overlap of a sphere on a wall of the same material at speed v:
  // delta = (15 m v^2 / (16 E* sqrt(a)))^(2/5), 1 / E* = 2 (1 - nu^2) / E.
  const double m = c.particle.density * kPi * std::pow(c.particle.diameter, 3) / 6;
  const double estar = c.particle.youngs_modulus / (2 * (1 - c.particle.poisson_ratio * c.particle.poisson_ratio));
  const double delta = std::pow(15 * m * v * v / (16 * estar * std::sqrt(a)), 0.4);
  const auto p = e.particles()[0];
  std::cout << "grain bounce: deepest centre " << (x_max - (face - a)) * 1e9 << " nm past contact (elastic Hertz " << delta * 1e9
            << " nm), restitution " << -p.v.x() / v << " (material "
            << c.particle.restitution << "), dt " << e.dt() << " s\n";
  // Damping (restitution 0.5) makes the overlap smaller than the elastic one.
  EXPECT_GT(x_max - (face - a), 0.5 * delta) << "touched the grain face (elastic Hertz overlap " << delta << " m)";
  EXPECT_LT(x_max - (face - a), 1.05 * delta) << "penetrated the grain deeper than the Hertz overlap";
  EXPECT_LT(p.v.x(), 0.0) << "bounced back";
  EXPECT_NEAR(-p.v.x() / v, c.particle.restitution, 0.05 * c.particle.restitution);
  EXPECT_NEAR(p.x.y(), 55e-6, 1e-9);  // head-on: no sideways motion
}

}  // namespace
}  // namespace mmval::particles

namespace mmval::particles {
namespace {

// The overdamped engine against LIGGGHTS on a shared window: 30 particles in a
// Hele-Shaw channel with a sticky bottom, same forces (HydroModel), no Brownian
// motion (LIGGGHTS has none), gravity x400 so that captures happen within
// 0.03 s. Particles that touch nothing differ by the inertial lag u tau_p
// ~ 1e-9 m plus the overdamped step's explicit error (measured < 30 nm at
// max_step_fraction 0.01): the median particle must agree within 30 nm. The
// few that collide differ after contact (Hertz with friction against
// frictionless hard spheres, measured up to 0.54 um), and a particle one
// engine captures and the other does not (allowed below) drifts apart at the
// plate (4.7 um by the end with both engines lagging the wall shear, Goldman,
// Cox & Brenner): RMS over all particles and times within 0.4 um (measured
// 0.33 um with one capture apart); captures matched within one particle.
TEST(EngineComparison, OverdampedMatchesLiggghtsOnSharedWindow) {
  SceneConfig c;
  c.brownian = false;
  c.gravity = 9.81 * 400;
  c.attachment.grains = false;
  c.particle.youngs_modulus = 1e5;  // softened: the DEM step is 1.4e-7 s
  c.work_dir = mmval::test::scratch("mmval-liggghts-test-compare");
  auto flow = std::make_shared<HeleShawChannel>(400e-6, 100e-6, 20e-6, 7e-4);
  const auto pos = sampleInlet(*flow, c.particle.radius(), 20e-6, 60e-6, 30, 17, {});
  LiggghtsEngine lg(flow, c);
  SceneConfig fine = c;
  fine.max_step_fraction = 0.01;
  OverdampedEngine od(flow, fine);
  const EngineComparison r = compareEngines(lg, od, pos, 0.03, 0.003);
  std::cout << r.toJson().dump(2) << "\n";
  EXPECT_LT(r.median_final_difference, 30e-9);
  EXPECT_LT(r.rms_position_difference, 0.4e-6);
  EXPECT_GT(r.captured_reference, 0);
  EXPECT_LE(std::abs(r.captured_reference - r.captured_candidate), 1);
  EXPECT_GE(r.captured_both, r.captured_reference - 1);
}

// The version the engine records is the one LIGGGHTS prints as the first line of
// its log, and it carries the upstream version of the installed Debian package
// (dpkg's "3.8.0+repack1-9+b2" -> "3.8.0") when dpkg knows the package.
TEST(Liggghts, VersionIsTheOneItsLogHeaderPrints) {
  auto flow = std::make_shared<UniformFlow>(Vec2(0, 0), 40e-6, Bounds2{0, 60e-6, 0, 60e-6});
  const SceneConfig c = quietScene("version");
  std::string version;
  {
    LiggghtsEngine e(flow, c);
    version = e.engineVersion();
  }  // closing LIGGGHTS flushes and closes its log
  std::ifstream log(c.work_dir / "liggghts.log");
  std::string first;
  ASSERT_TRUE(std::getline(log, first)) << c.work_dir;
  const auto from_log = liggghtsVersionFromHeader(first);
  ASSERT_TRUE(from_log.has_value()) << first;
  EXPECT_EQ(version, *from_log);
  FILE* pipe = popen("dpkg-query -W -f '${Version}' libliggghts3 2>/dev/null", "r");
  std::string package;
  if (pipe != nullptr) {
    char buf[256];
    while (std::fgets(buf, sizeof buf, pipe) != nullptr) package += buf;
    pclose(pipe);
  }
  const std::string upstream = package.substr(0, package.find_first_of("+-~"));
  if (upstream.empty()) GTEST_SKIP() << "dpkg does not know libliggghts3; the log header check above passed";
  EXPECT_NE(version.find(" " + upstream), std::string::npos) << version << " against the package's " << package;
}

// Before the first insertion there is nothing to integrate: advancing moves the
// clock (to the nearest whole step) without running LIGGGHTS, which would end the
// process on a run without atoms; particles inserted later then move as usual.
TEST(Liggghts, AdvancingWithoutParticlesOnlyMovesTheClock) {
  const double u_mean = 1e-3, h = 100e-6;
  auto flow = std::make_shared<UniformFlow>(Vec2(u_mean, 0), h, Bounds2{0, 200e-6, 0, 100e-6});
  const SceneConfig c = quietScene("empty-start");
  LiggghtsEngine e(flow, c);
  const double tau = relaxationTime(c.fluid, c.particle);
  e.advance(2 * tau);
  EXPECT_NEAR(e.time(), 2 * tau, 0.5 * e.dt());
  EXPECT_EQ(e.stats().steps, 0);
  e.insert({Vec3(50e-6, 50e-6, 0.5 * h)});
  e.advance(7 * tau);
  // Released at 2 tau, it relaxes for 5 tau: v = 1.5 u_mean (1 - exp(-5)), as in SphereRelaxesToFlowVelocityWithTauP.
  const double uf = 1.5 * u_mean, t = e.time() - 2 * tau;
  EXPECT_NEAR(e.particles()[0].v.x(), uf * (1 - std::exp(-t / tau)), 2e-3 * uf);
}

}  // namespace
}  // namespace mmval::particles
