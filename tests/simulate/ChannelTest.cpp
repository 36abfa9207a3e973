// Channel flows with exact solutions: plane Poiseuille (pressure- and
// velocity-driven), the depth-averaged (Brinkman-Hele-Shaw) duct, and
// Poiseuille flow between immersed walls inclined to the grid.
#include <cmath>
#include <memory>

#include <gtest/gtest.h>

#include "mmval/simulate/FlowSolver.hpp"

using namespace mmval::simulate;

namespace {

FlowProblem periodicChannel(int ny, double width, double G, double mu) {
  FlowProblem p;
  p.x = uniformAxis(0, width / ny * 4, 4);
  p.y = uniformAxis(0, width, ny);
  p.boundary[0].type = p.boundary[1].type = BoundaryType::periodic;
  p.viscosity = mu;
  p.body_force = {G, 0};
  return p;
}

}  // namespace

TEST(Channel, PoiseuilleFlowRateSecondOrder) {
  const double W = 100e-6, G = 1e4, mu = 1e-3;
  const double exact = G * W * W * W / (12 * mu);
  double prev = 0;
  for (int ny : {8, 16, 32}) {
    SteadyFlowSolver s(periodicChannel(ny, W, G, mu));
    s.solve();
    const double q = s.flowRate(Side::west);
    const double err = std::abs(q - exact) / exact;
    // MAC with a mirror ghost at the wall: the flow rate is high by 2 / ny^2
    // (measured; second order), 0.2 % at 32 cells.
    EXPECT_NEAR(err * ny * ny, 2.0, 0.05) << "ny " << ny << " q " << q << " exact " << exact;
    if (prev > 0) {
      EXPECT_NEAR(prev / err, 4.0, 0.2) << "second order";
    }
    prev = err;
    EXPECT_LT(s.maxRelativeDivergence(), 1e-10);
  }
}

TEST(Channel, VelocityInletPressureOutlet) {
  // Parabolic inflow of mean U into a channel of length 8 W: the pressure gradient far from the inlet is 12 mu U / W^2.
  const double W = 1e-3, L = 8e-3, mu = 1e-3, Umean = 1e-3;
  FlowProblem p;
  p.x = uniformAxis(0, L, 128);
  p.y = uniformAxis(0, W, 32);
  p.viscosity = mu;
  p.boundary[0].type = BoundaryType::velocity;
  p.boundary[0].velocity = [&](double y) { return 6 * Umean * y * (W - y) / (W * W); };
  p.boundary[1].type = BoundaryType::pressure;
  p.inertia = true;
  p.density = 1000;  // Re = 1
  SteadyFlowSolver s(p);
  s.solve();
  const double G = (s.pressureAt(0.25 * L, 0.5 * W) - s.pressureAt(0.75 * L, 0.5 * W)) / (0.5 * L);
  EXPECT_NEAR(G / (12 * mu * Umean / (W * W)), 1.0, 5e-3);  // issue 4: 0.5 %
  EXPECT_NEAR(s.flowRate(Side::east) / s.flowRate(Side::west), 1.0, 1e-10);  // mass conservation
  EXPECT_NEAR(s.flowRate(Side::west) / (Umean * W), 1.0, 1e-3);  // inflow profile sampled at 32 cell centres
  EXPECT_GT(s.stats().newton_iterations, 0);
}

TEST(Channel, PressureDrivenInletOutlet) {
  // Fixed pressures at both ends (the paper's set-up): q = dp W^3 / (12 mu L).
  const double W = 1e-4, L = 4e-4, mu = 1e-3, dp = 1.0;
  FlowProblem p;
  p.x = uniformAxis(0, L, 16);
  p.y = uniformAxis(0, W, 32);
  p.viscosity = mu;
  p.boundary[0].type = BoundaryType::pressure;
  p.boundary[0].pressure = dp;
  p.boundary[1].type = BoundaryType::pressure;
  SteadyFlowSolver s(p);
  s.solve();
  const double exact = dp / L * W * W * W / (12 * mu);
  EXPECT_NEAR(s.flowRate(Side::east) / exact, 1.0 + 2.0 / (32 * 32), 1e-4);  // the MAC wall error, as in the periodic channel
}

TEST(Channel, DepthAveragedDuct) {
  // Brinkman-Hele-Shaw channel: Q = G h^2 W / (12 mu) (1 - tanh(k W/2) / (k W/2)) h, k = sqrt(12) / h.
  const double W = 200e-6, h = 20e-6, G = 1e4, mu = 1e-3;
  FlowProblem p = periodicChannel(128, W, G, mu);
  p.depth = h;
  SteadyFlowSolver s(p);
  s.solve();
  const double k = std::sqrt(12.0) / h;
  const double exact = G * h * h * W / (12 * mu) * (1 - std::tanh(k * W / 2) / (k * W / 2));
  EXPECT_NEAR(s.flowRate(Side::west) / exact, 1.0, 5e-3);
}

namespace {

/// Solid stripes of normal (-1, 2) / sqrt 5 and period P = Lx / sqrt 5, so they repeat with the box
/// [0, Lx] x [0, Lx / 2]; the fluid layers between them are w wide and no wall is along a grid axis.
class InclinedStripes final : public Shape {
 public:
  InclinedStripes(double Lx, double w) : m_P(Lx / std::sqrt(5.0)), m_w(w) {}
  int bodyAt(double x, double y) const override {
    const double s = (-x + 2 * y) / std::sqrt(5.0) + 0.3 * m_P;  // offset: the walls cut the cells off the nodes
    return s - m_P * std::floor(s / m_P) > m_w ? 0 : -1;
  }
  int bodies() const override { return 1; }
  Eigen::Vector2d centre(int) const override { return {0, 0}; }

 private:
  double m_P, m_w;
};

/// Relative error of the superficial velocity of Stokes flow through the inclined layers, driven by
/// G along them, on nx x nx/2 cells. Exact: layer flux G w^3 / (12 mu) per period P, x-part 2 / sqrt 5.
double inclinedChannelError(int nx) {
  const double Lx = 1, mu = 1e-3, G = 0.06, P = Lx / std::sqrt(5.0), w = 0.6 * P;
  FlowProblem p;
  p.x = uniformAxis(0, Lx, nx);
  p.y = uniformAxis(0, 0.5 * Lx, nx / 2);
  for (auto& b : p.boundary) b.type = BoundaryType::periodic;
  p.viscosity = mu;
  p.body_force = G * Eigen::Vector2d(2, 1) / std::sqrt(5.0);
  p.shape = std::make_shared<InclinedStripes>(Lx, w);
  SteadyFlowSolver s(p);
  s.solve();
  const double exact = G * w * w * w / (12 * mu) / P * 2 / std::sqrt(5.0);
  return s.superficialVelocity() / exact - 1;
}

}  // namespace

// Walls inclined to the grid: the test of the continuity at cut cells. Walls along a grid axis
// converge at second order (a 0.3-wide layer along x on the same grids: +1.4 %, +0.35 %); inclined
// ones are first order, because the cells the surface cuts see the node value times the whole face
// where part of the face is solid (or, for a node inside the body, fluid). Measured flow rate error
// at 40 x 20 cells (~11 across the layer) and 80 x 40:
//   node value x whole face, solid nodes zero (before)                 -2.2 %   -1.15 %
//   fluid part of faces with a fluid node (m_open, as now)              -0.95 %  -0.53 %
//   plus the fluid part of faces with a solid node, from the fluid
//   neighbour (pressure force on it by transpose; not used: Sangani-
//   Acrivos phi 0.05 at 32 cells went from -0.2 % to +12 %)            +0.14 %  +0.008 %
// so what is left is the solid nodes' share, and the cell pressures next to the walls still scatter
// by O(mu U / w) without converging. (Extrapolating the fluid linearly into the solid faces instead
// cuts the error ~10x but puts a net mass source at closed bodies, 3-4 % of the inflow at D/10.)
TEST(Channel, InclinedImmersedWallsConverge) {
  const double e40 = inclinedChannelError(40), e80 = inclinedChannelError(80);
  EXPECT_LT(std::abs(e40), 0.015) << "40 cells: flow rate error " << e40;  // -2.2 % with the whole faces
  EXPECT_LT(std::abs(e80), 0.6 * std::abs(e40)) << "40 cells: " << e40 << ", 80 cells: " << e80;
}
