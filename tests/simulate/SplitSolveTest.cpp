// The friction split (SolverOptions::linear = "iterative" on a depth-averaged Stokes problem):
// GMRES preconditioned on the right by the block upper-triangular Schur factorisation, the Schur complement
// by the LU of B diag(A)^-1 B^T and the velocity block by a Gauss-Seidel sweep (CoupledSystem).
// Reference: the direct LU of the same saddle-point matrix (the solver every micromodel solve
// used). A grain mask at the micromodel's scales (10 um pixels, 20 um deep, 1 cell per pixel)
// with a thinned aperture in part of the pore space (deposit layers), 96 x 48 cells.
// Tolerances: GMRES (right preconditioning) stops when the true residual is 1e-12 of the right-
// hand side; the velocity error is that times the condition number of the scaled system, which
// on this mask is measured at ~1e-11 of the largest velocity; the test allows 1e-8 (the largest
// velocity deviation measured on the full Pore2Chip chip at 750k unknowns, where the LU's own
// rounding is ~1e-8), and the flow rate 1e-10. Iterations: ~20 on the full chip; the bound 40
// fails if the Schur approximation stops fitting (GAMG stalled at 836 iterations there).
// The fallback: a budget of 3 iterations cannot converge; the solve must then give the direct
// LU's answer bit for bit, say so in its stats, and the next solve must try the split again.
// 1 MPI rank; each test well under a second.
#include <cmath>
#include <memory>
#include <random>

#include <gtest/gtest.h>

#include "mmval/simulate/FlowSolver.hpp"
#include "mmval/simulate/Geometry.hpp"

using namespace mmval::simulate;

namespace {

constexpr double kPixel = 10e-6, kDepth = 20e-6;
constexpr int kCols = 96, kRows = 48;

/// Random disc grains (radius 2-5 px) on a kCols x kCols mask, west to east by 1 Pa, walls north and south;
/// the aperture is 40-100 % of the depth in a third of the cells (the deposit layers of a micromodel).
FlowProblem grainChip() {
  Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic> solid = Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic>::Constant(kRows, kCols, false);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> ux(0, kCols), uy(0, kRows), ur(2, 5);
  for (int g = 0; g < 40; ++g) {
    const double cx = ux(rng), cy = uy(rng), r = ur(rng);
    for (int j = 0; j < kRows; ++j)
      for (int i = 8; i < kCols - 8; ++i)  // open inlet and outlet strips keep a connected pore space
        if (std::hypot(i + 0.5 - cx, j + 0.5 - cy) < r) solid(j, i) = true;
  }
  FlowProblem p;
  p.x = uniformAxis(0, kCols * kPixel, kCols);
  p.y = uniformAxis(0, kRows * kPixel, kRows);
  p.boundary[0].type = p.boundary[1].type = BoundaryType::pressure;
  p.boundary[0].pressure = 1.0;
  p.boundary[2].type = p.boundary[3].type = BoundaryType::no_slip;
  p.viscosity = 1e-3;
  p.depth = kDepth;
  p.depth_field = Eigen::ArrayXXd::Constant(kRows, kCols, kDepth);
  std::uniform_real_distribution<double> thin(0.4, 1.0), pick(0, 1);
  for (int j = 0; j < kRows; ++j)
    for (int i = 0; i < kCols; ++i)
      if (pick(rng) < 1.0 / 3) p.depth_field(j, i) = thin(rng) * kDepth;
  p.shape = std::make_shared<MaskShape>(solid, kPixel);
  return p;
}

SolverOptions split(int budget) {
  SolverOptions o;
  o.linear = "iterative";
  o.linear_rtol = 1e-12;
  o.linear_max_iterations = budget;
  return o;
}

double deviation(const SteadyFlowSolver& a, const SteadyFlowSolver& b) {
  const double umax = std::max(b.u().abs().maxCoeff(), b.v().abs().maxCoeff());
  return std::max((a.u() - b.u()).abs().maxCoeff(), (a.v() - b.v()).abs().maxCoeff()) / umax;
}

TEST(SplitSolve, GivesTheDirectLuAnswerOnAGrainChip) {
  SteadyFlowSolver direct(grainChip()), it(grainChip(), split(60));
  direct.solve();
  const FlowStats& s = it.solve();
  EXPECT_EQ(s.linear_solver, "iterative");
  EXPECT_FALSE(s.linear_fallback);
  EXPECT_LE(s.linear_iterations, 40);
  EXPECT_GT(s.linear_iterations, 1);
  const double q = direct.flowRate(Side::east);
  ASSERT_GT(q, 0);
  EXPECT_NEAR(it.flowRate(Side::east), q, 1e-10 * q);
  EXPECT_LT(deviation(it, direct), 1e-8);
  // Deterministic: a second solver gives the same bytes.
  SteadyFlowSolver again(grainChip(), split(60));
  again.solve();
  EXPECT_TRUE((again.u() == it.u()).all() && (again.v() == it.v()).all() && (again.p() == it.p()).all());
}

TEST(SplitSolve, FallsBackToTheDirectLuWhenFgmresRunsOut) {
  SteadyFlowSolver direct(grainChip()), it(grainChip(), split(3));
  direct.solve();
  const FlowStats s = it.solve();
  EXPECT_TRUE(s.linear_fallback);
  EXPECT_EQ(s.linear_solver, "direct");
  EXPECT_EQ(s.linear_iterations, 3 + 1);  // the failed FGMRES's 3, the LU solve's 1
  EXPECT_TRUE((it.u() == direct.u()).all() && (it.v() == direct.v()).all() && (it.p() == direct.p()).all());
  // The next solve tries the split first again (and falls back again on this budget).
  it.update(grainChip());
  const FlowStats t = it.solve();
  EXPECT_TRUE(t.linear_fallback);
  EXPECT_EQ(t.linear_iterations, 3 + 1);
  EXPECT_TRUE((it.u() == direct.u()).all());
}

}  // namespace
