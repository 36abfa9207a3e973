// Pressure components without a pressure level (FlowOperator::pinClosedComponents): a sharp
// solve of a pixel mask whose grains hold enclosed pockets. At 0.5 cells per pixel (every node on
// a pixel corner) a lone pore pixel inside a grain opens the face between two cells whose centres
// are in the grain (each merges into the other, a chain that closes on itself), and three pore
// pixels in a row make two fluid cells with no way out: both are components of cells with no
// pressure boundary, which made the system singular ("the fluid solution is not finite", as the
// micromodel scene's deposits did). Periodic too: there the constructor's one reference cell (the
// first cell with a free face) falls in the first pocket and left the channel without a level.
//
// Reference: the channel between the walls y = 40 and 200 um (8 cells of 20 um, walls on cell
// faces) is plane Poiseuille for the continuum, q = G H^3 / (12 mu); the sharp method's cut
// stencil (wall at half the link, the flux u_P / (h / 2)) gives the fully developed discrete
// profile exactly as the parabola with walls moved out by s = (h / 2)(sqrt(1 + (H/h)^2) - H/h),
// whose node sum is q_h = G (H^3 + 2 h^2 H) / (12 mu): 3.1 % above the continuum at H = 8 h
// (second order). The solve must give q_h to rounding (1e-9), and the same flux as the mask
// with the pockets filled (1e-12: the pockets do not touch the channel's equations).
#include <gtest/gtest.h>

#include <cmath>

#include "mmval/simulate/FlowSolver.hpp"
#include "mmval/simulate/Geometry.hpp"
#include "mmval/simulate/Grid.hpp"

namespace mmval::simulate {
namespace {

using Mask = Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic>;

constexpr double kPixel = 10e-6, kMu = 1e-3, kDp = 1.0;  // m, Pa s, Pa
constexpr int kRows = 24, kCols = 24, kWall = 4;          // pixels; the channel is rows kWall .. kRows - kWall from the bottom

/// Solid walls 4 pixels thick above and below the channel; `pockets`: pore pixels inside the
/// lower wall (y counted in pixels from the bottom): one at (10, 1) and three at (17-19, 1).
/// One column more than the domain (written before MaskShape read its edge pixel at the image
/// edge, MaskEdgeTest; kept: the outlet's face nodes at x = kCols pixels see walls either way).
Mask channel(bool pockets) {
  Mask m = Mask::Constant(kRows, kCols + 1, false);
  const auto set = [&](int x, int y, bool solid) { m(kRows - 1 - y, x) = solid; };
  for (int y = 0; y < kRows; ++y)
    for (int x = 0; x <= kCols; ++x) set(x, y, y < kWall || y >= kRows - kWall);
  if (pockets)
    for (const int x : {10, 17, 18, 19}) set(x, 1, false);
  return m;
}

/// 0.5 cells per pixel, sharp walls; pressure inlet and outlet (kDp) or periodic in x with the
/// same mean gradient as a body force.
FlowProblem problem(const Mask& m, bool periodic) {
  FlowProblem p;
  p.x = uniformAxis(0, kCols * kPixel, kCols / 2);
  p.y = uniformAxis(0, kRows * kPixel, kRows / 2);
  p.viscosity = kMu;
  p.shape = std::make_shared<MaskShape>(m, kPixel);
  p.method = ImmersedMethod::sharp;
  if (periodic) {
    p.boundary[0].type = p.boundary[1].type = BoundaryType::periodic;
    p.body_force = {kDp / (kCols * kPixel), 0};
  } else {
    p.boundary[0].type = p.boundary[1].type = BoundaryType::pressure;
    p.boundary[0].pressure = kDp;
  }
  return p;
}

void expectPoiseuilleWithPinnedPockets(bool periodic) {
  SteadyFlowSolver s(problem(channel(true), periodic));
  ASSERT_NO_THROW(s.solve());
  SteadyFlowSolver filled(problem(channel(false), periodic));
  filled.solve();
  const double G = kDp / (kCols * kPixel), H = (kRows - 2 * kWall) * kPixel, h = 2 * kPixel;
  const double q_h = G * (H * H * H + 2 * h * h * H) / (12 * kMu);
  const double q = s.flowRate(Side::east);
  EXPECT_NEAR(q, q_h, 1e-9 * q_h) << "continuum Poiseuille " << G * H * H * H / (12 * kMu);
  EXPECT_NEAR(q, filled.flowRate(Side::east), 1e-12 * q_h);
  EXPECT_NEAR(s.flowRate(Side::west), q, 1e-12 * q_h);
  // Nothing moves in the pockets: the faces x = 100 um and x = 180 um of the bottom cell row.
  const double umax = s.u().abs().maxCoeff();
  EXPECT_LE(std::abs(s.u()(0, 5)), 1e-12 * umax);
  EXPECT_LE(std::abs(s.u()(0, 9)), 1e-12 * umax);
  EXPECT_TRUE(s.p().isFinite().all());
}

TEST(PressureComponent, EnclosedPocketsOfAPressureDrivenChannelArePinned) { expectPoiseuilleWithPinnedPockets(false); }

TEST(PressureComponent, PeriodicChannelKeepsItsLevelWhenTheFirstFreeCellIsAPocket) { expectPoiseuilleWithPinnedPockets(true); }

}  // namespace
}  // namespace mmval::simulate
