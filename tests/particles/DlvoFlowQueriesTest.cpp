// The overdamped engine under the dlvo rule asks its flow through a memo of point queries
// (OverdampedEngine.cpp, FlowQueryMemo): the values must be the flow's own at every point, and a
// re-solve (a new version() of the flow) must drop them. Both are checked against the closed-form
// velocity of a particle on the depth profile, v = u_mean (6 z (h - z) / h^2 - 2 a^2 / h^2) at
// height z (Faxen's curvature term; hindrance, lag, gravity and Brownian motion off, and the
// particles far beyond the DLVO force's range from the plates, so nothing else moves them).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

#include "mmval/particles/FlowField.hpp"
#include "mmval/particles/OverdampedEngine.hpp"

namespace mmval::particles {
namespace {

constexpr double kDx = 10e-6, kDepth = 20e-6;
constexpr int kNx = 60, kNy = 40;

SceneConfig dlvoPlainScene() {
  SceneConfig c;
  c.brownian = false;
  c.gravity = 0;
  c.wall_hindrance = false;
  c.attachment.rule = AttachmentModel::Rule::dlvo;
  c.attachment.capture_distance = 0.1e-6;
  c.attachment.grains = false;
  c.attachment.chemistry.electrolyte.ionic_strength = 10.0;  // mol/m3
  c.attachment.chemistry.collector_potential = -0.077;
  c.attachment.chemistry.electrolyte.temperature = c.fluid.temperature;
  return c;
}

/// Node field u_x = u0 + s y (bilinear between nodes: exact for a linear field), no solid, uniform depth.
void setShear(GriddedFlow& g, double u0, double s) {
  const auto n = static_cast<std::size_t>(kNx) * kNy;
  std::vector<double> u(n), v(n, 0.0), h(n, kDepth);
  for (int j = 0; j < kNy; ++j)
    for (int i = 0; i < kNx; ++i) u[static_cast<std::size_t>(j) * kNx + i] = u0 + s * j * kDx;
  g.update(u, v, h, std::vector<std::uint8_t>(n, 0));
}

double profile(const SceneConfig& c, double z) {
  const double a = c.particle.radius();
  return 6.0 * z * (kDepth - z) / (kDepth * kDepth) - 2.0 * a * a / (kDepth * kDepth);
}

// 2400 particles at distinct (x, y), more than the memo's 4096 slots hold as two points each, so
// points share slots: each particle's displacement over one step must still be its own u(y) v dt.
// Tolerance 1e-9 relative: a double's round-off over a handful of operations (a wrong slot gives a
// velocity of another row, off by s dy / u ~ 1e-3 and more).
TEST(DlvoFlowQueries, EveryPointGetsItsOwnVelocity) {
  const SceneConfig c = dlvoPlainScene();
  auto g = std::make_shared<GriddedFlow>(kNx, kNy, 0, 0, kDx, kDx);
  const double u0 = 1e-4, s = 2.0;  // 1/s: u from 0.1 to 0.88 mm/s across the field
  setShear(*g, u0, s);
  OverdampedEngine e(g, c);
  const double z = 0.5 * kDepth;
  std::vector<Vec3> xs;
  for (int i = 0; i < 40; ++i)
    for (int j = 0; j < 60; ++j) xs.emplace_back(20e-6 + i * 6.1e-6, 20e-6 + j * 5.9e-6, z);
  e.insert(xs);
  const double dt = 1.5e-4;  // < 0.1 a / v_max = 1.9e-4 s (max_step_fraction 0.1): one step
  e.advance(dt);
  ASSERT_EQ(e.stats().steps, 1);
  const auto ps = e.particles();
  ASSERT_EQ(ps.size(), xs.size());
  for (std::size_t k = 0; k < ps.size(); ++k) {
    const double expected = (u0 + s * xs[k].y()) * profile(c, z) * dt;
    EXPECT_NEAR(ps[k].x.x() - xs[k].x(), expected, 1e-9 * expected) << "particle " << k;
    EXPECT_EQ(ps[k].x.y(), xs[k].y());
  }
}

// A particle at rest in still fluid keeps its (x, y) exactly, so a memo that outlived a re-solve
// would hand it the old (zero) velocity: after the flow is re-solved to u the particle must move
// u v t (1e-9 relative, round-off), not 0.
TEST(DlvoFlowQueries, AReSolvedFlowIsSeen) {
  const SceneConfig c = dlvoPlainScene();
  auto g = std::make_shared<GriddedFlow>(kNx, kNy, 0, 0, kDx, kDx);
  setShear(*g, 0.0, 0.0);
  OverdampedEngine e(g, c);
  const Vec3 x0(100e-6, 150e-6, 0.4 * kDepth);
  e.insert({x0});
  e.advance(1.0);
  ASSERT_EQ(e.particles()[0].x, x0);
  const std::uint64_t v0 = g->version();
  const double u = 2e-4;
  setShear(*g, u, 0.0);
  ASSERT_NE(g->version(), v0);
  e.advance(1.5);
  const double moved = e.particles()[0].x.x() - x0.x(), expected = u * profile(c, x0.z()) * 0.5;
  EXPECT_NEAR(moved, expected, 1e-9 * expected);
}

}  // namespace
}  // namespace mmval::particles
