// Variable depth (aperture) in the depth-averaged solver (FlowProblem::depth_field):
// a constant field must reproduce the scalar depth to round-off, and in the
// friction-dominated limit (chip much longer and wider than deep, slip sides)
// the flux must approach the exact Reynolds-equation (lubrication) references
//   two depths in series:    Q = dp / sum_i(12 mu L_i / (h_i^3 W))
//   two strips side by side: Q = dp sum_i(h_i^3 W_i) / (12 mu L)
// (Q: volume flux = flowRate x reference depth). In series the model is exact
// on any grid: the face depth at the step is the harmonic mean of h^3 (the
// exact series conductance) and the in-plane viscous stresses telescope to no
// net force along a straight slot. Side by side, the Brinkman (in-plane
// viscous) term couples the strips over ~ h / sqrt(12); its effect on Q falls
// like h / W, and the discrete flux converges to the model's own exact
// solution (exponential layers either side of the interface) as the grid is
// refined. 1 MPI rank, small grids (well under a second).
#include <cmath>
#include <iostream>
#include <memory>

#include <gtest/gtest.h>

#include "mmval/simulate/FlowSolver.hpp"

using namespace mmval::simulate;

namespace {

constexpr double kMu = 1e-3, kDp = 1.0;

FlowProblem slot(double L, double W, int nx, int ny, double h_ref) {
  FlowProblem p;
  p.x = uniformAxis(0, L, nx);
  p.y = uniformAxis(0, W, ny);
  p.boundary[0].type = p.boundary[1].type = BoundaryType::pressure;
  p.boundary[0].pressure = kDp;
  p.boundary[2].type = p.boundary[3].type = BoundaryType::slip;
  p.viscosity = kMu;
  p.depth = h_ref;
  return p;
}

double maxAbs(const Eigen::ArrayXXd& a) { return a.abs().maxCoeff(); }

/// Relative error of the series (two depths along the flow) flux on an L x W slot, step at L / 2.
double seriesError(double L, double W, int nx, double h1, double h2, double* mass = nullptr) {
  FlowProblem p = slot(L, W, nx, 4, h1);
  p.depth_field = Eigen::ArrayXXd::Constant(4, nx, h1);
  p.depth_field.rightCols(nx / 2) = h2;
  SteadyFlowSolver s(p);
  s.solve();
  const double exact = kDp / (12 * kMu * (0.5 * L) / (h1 * h1 * h1 * W) + 12 * kMu * (0.5 * L) / (h2 * h2 * h2 * W));
  if (mass != nullptr) *mass = std::abs(s.flowRate(Side::east) / s.flowRate(Side::west) - 1.0);
  return s.flowRate(Side::east) * p.depth / exact - 1.0;
}

/// Flux of the side-by-side strips (interface at W / 2, h1 below, h2 above), volume per time.
double stripsFlux(double L, double W, int ny, double h1, double h2) {
  FlowProblem p = slot(L, W, 4, ny, h1);
  p.depth_field = Eigen::ArrayXXd::Constant(ny, 4, h1);
  p.depth_field.bottomRows(ny / 2) = h2;  // rows are y cells: the upper half (j >= ny / 2) gets h2
  SteadyFlowSolver s(p);
  s.solve();
  EXPECT_NEAR(s.flowRate(Side::east) / s.flowRate(Side::west), 1.0, 1e-10);
  return s.flowRate(Side::east) * p.depth;
}

double stripsReynolds(double L, double W, double h1, double h2) { return kDp * (h1 * h1 * h1 + h2 * h2 * h2) * 0.5 * W / (12 * kMu * L); }

/// The model's exact solution for the strips: -G + mu u'' - 12 mu u / h_i^2 = 0 in
/// each strip, slip (u' = 0) at y = 0 and W, u and u' continuous at W / 2:
/// u_i = U_i + A_i cosh(k_i s_i) / cosh(k_i W / 2), U_i = G h_i^2 / (12 mu),
/// k_i = sqrt(12) / h_i, s_i the distance from the strip's outer side.
double stripsBrinkman(double L, double W, double h1, double h2) {
  const double G = kDp / L, U1 = G * h1 * h1 / (12 * kMu), U2 = G * h2 * h2 / (12 * kMu);
  const double k1 = std::sqrt(12.0) / h1, k2 = std::sqrt(12.0) / h2;
  const double th1 = std::tanh(0.5 * k1 * W), th2 = std::tanh(0.5 * k2 * W);
  const double T1 = k1 * th1, T2 = k2 * th2;
  const double A1 = -(U1 - U2) * T2 / (T1 + T2), A2 = (U1 - U2) * T1 / (T1 + T2);
  return h1 * (U1 * 0.5 * W + A1 * th1 / k1) + h2 * (U2 * 0.5 * W + A2 * th2 / k2);
}

}  // namespace

TEST(ChannelDepthField, ConstantFieldReproducesTheScalarDepth) {
  // A chip with a penalized and a sharp obstacle: same equations, so the same
  // numbers to round-off (observed: bit for bit; tolerance: round-off class).
  for (ImmersedMethod method : {ImmersedMethod::penalized, ImmersedMethod::sharp}) {
    FlowProblem a = slot(400e-6, 200e-6, 40, 20, 20e-6);
    a.shape = std::make_shared<Circles>(std::vector<Circle>{{150e-6, 90e-6, 40e-6}, {290e-6, 130e-6, 30e-6}});
    a.method = method;
    FlowProblem b = a;
    b.depth_field = Eigen::ArrayXXd::Constant(20, 40, 20e-6);
    SteadyFlowSolver sa(a), sb(b);
    sa.solve();
    sb.solve();
    const double us = maxAbs(sa.u()), ps = maxAbs(sa.p());
    EXPECT_LE(maxAbs(sa.u() - sb.u()), 1e-12 * us);
    EXPECT_LE(maxAbs(sa.v() - sb.v()), 1e-12 * us);
    EXPECT_LE(maxAbs(sa.p() - sb.p()), 1e-12 * ps);
    EXPECT_NEAR(sb.flowRate(Side::east) / sa.flowRate(Side::east), 1.0, 1e-12);
  }
}

TEST(ChannelDepthField, TwoDepthsInSeriesGiveTheReynoldsFlux) {
  // 20 um then 10 um deep, step at a cell face; 1 and 4 mm long (cells 25 um).
  // Exact for this discretisation (see the top comment): observed ~1e-15, so the
  // tolerance is round-off class; the mass balance is div(h u) = 0.
  const double W = 400e-6, h1 = 20e-6, h2 = 10e-6;
  for (int nx : {40, 160}) {
    const double L = nx * 25e-6;
    double mass = 0;
    const double e = seriesError(L, W, nx, h1, h2, &mass);
    EXPECT_LT(std::abs(e), 1e-12) << "L = " << L;
    EXPECT_LT(mass, 1e-12) << "what enters at 20 um depth must leave at 10 um";
  }
  // A depth that halves and recovers: each segment's resistance adds.
  FlowProblem p = slot(3e-3, W, 120, 4, h1);
  p.depth_field = Eigen::ArrayXXd::Constant(4, 120, h1);
  p.depth_field.middleCols(40, 40) = h2;
  SteadyFlowSolver s(p);
  s.solve();
  const double exact = kDp / (12 * kMu * 2e-3 / (h1 * h1 * h1 * W) + 12 * kMu * 1e-3 / (h2 * h2 * h2 * W));
  EXPECT_NEAR(s.flowRate(Side::east) * p.depth / exact, 1.0, 1e-12);
}

TEST(ChannelDepthField, TwoStripsSideBySideApproachTheReynoldsFlux) {
  // 20 um and 10 um deep strips of equal width, flow along them.
  const double L = 400e-6, h1 = 20e-6, h2 = 10e-6;
  // Against the model's exact Brinkman solution: second order in the cell size
  // (observed errors 1.6e-3, 4.9e-4, 1.3e-4, 3.3e-5 at 5, 2.5, 1.25, 0.625 um
  // cells: ratios 3.3, 3.8, 3.9; at 5 um the cell is wider than the layer, 1 / k_2 = 2.9 um).
  const double W = 400e-6, ref = stripsBrinkman(L, W, h1, h2);
  double prev = 0;
  for (int ny : {160, 320, 640}) {
    const double e = stripsFlux(L, W, ny, h1, h2) / ref - 1.0;
    std::cout << "strips, W = 0.4 mm, " << ny << " cells across: error against the Brinkman solution " << e << "\n";
    if (prev != 0) {
      EXPECT_NEAR(prev / e, 4.0, 0.4) << "second order in the cell size";
    }
    prev = e;
  }
  EXPECT_LT(std::abs(prev), 5e-5);
  // Against the Reynolds (lubrication) flux: the Brinkman layer's share falls like
  // h / W (observed -1.1 % at W = 0.4 mm, -0.28 % at 1.6 mm, 1.25 um cells).
  const double e1 = stripsFlux(L, 400e-6, 320, h1, h2) / stripsReynolds(L, 400e-6, h1, h2) - 1.0;
  const double e4 = stripsFlux(L, 1600e-6, 1280, h1, h2) / stripsReynolds(L, 1600e-6, h1, h2) - 1.0;
  std::cout << "strips: error against the Reynolds flux " << e1 << " (W = 0.4 mm), " << e4 << " (W = 1.6 mm)\n";
  EXPECT_NEAR(e1 / e4, 4.0, 0.1) << "the Brinkman correction must fall like 1 / W";
  EXPECT_LT(std::abs(e4), 3e-3);
  EXPECT_NEAR(stripsBrinkman(L, 1600e-6, h1, h2) / stripsReynolds(L, 1600e-6, h1, h2) - 1.0, e4, 2e-4);
}

TEST(ChannelDepthFieldBadInput, WrongShapeOrNonPositiveDepthIsRefused) {
  FlowProblem p = slot(100e-6, 100e-6, 8, 8, 20e-6);
  p.depth_field = Eigen::ArrayXXd::Constant(8, 7, 20e-6);
  EXPECT_THROW(SteadyFlowSolver{p}, std::invalid_argument);
  p.depth_field = Eigen::ArrayXXd::Constant(8, 8, 20e-6);
  p.depth_field(3, 3) = 0.0;
  EXPECT_THROW(SteadyFlowSolver{p}, std::invalid_argument);
  p.depth_field(3, 3) = 20e-6;
  p.depth = 0.0;  // no reference depth
  EXPECT_THROW(SteadyFlowSolver{p}, std::invalid_argument);
}
