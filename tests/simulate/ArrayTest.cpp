// Stokes flow through a periodic square array of cylinders against Sangani &
// Acrivos (1982): F* = G L^2 / (mu U_darcy). Both immersed treatments.
#include <cmath>
#include <memory>

#include <gtest/gtest.h>

#include "mmval/simulate/FlowSolver.hpp"

using namespace mmval::simulate;

namespace {

struct ArrayResult {
  double fstar, force_balance, divergence;
};

ArrayResult solveArray(double phi, int n, ImmersedMethod method, const std::string& linear = "direct") {
  const double L = 1e-4, mu = 1e-3, G = 1.0;
  FlowProblem p = squareArrayProblem(L, n, phi, mu, G);
  p.method = method;
  SolverOptions o;
  o.linear = linear;
  SteadyFlowSolver s(p, o);
  s.solve();
  return {G * L * L / (mu * s.superficialVelocity()), s.bodyLoads()[0].force.x() / (G * L * L), s.maxRelativeDivergence()};
}

}  // namespace

// Sangani & Acrivos (1982) F*; tolerance 2 % at 32 cells per side.
// Measured (sharp, 32 cells): -0.17 % (0.05), -0.27 % (0.1), -0.34 % (0.2), -0.32 % (0.3), -0.92 % (0.5).
TEST(Array, SharpMatchesSanganiAcrivos) {
  const double phis[] = {0.05, 0.1, 0.2, 0.3, 0.5};
  const double ref[] = {15.56, 24.83, 51.53, 102.90, 532.55};
  for (int k = 0; k < 5; ++k) {
    const ArrayResult r = solveArray(phis[k], 32, ImmersedMethod::sharp);
    EXPECT_NEAR(r.fstar / ref[k], 1.0, 0.02) << "phi " << phis[k] << " F* " << r.fstar;
    // Self-consistency: the drag on the body balances the driving force (round-off class).
    EXPECT_NEAR(r.force_balance, 1.0, 1e-9);
    EXPECT_LT(r.divergence, 1e-9);
  }
}

TEST(Array, PenalizedIsFirstOrderAndLessAccurate) {
  // The volume-fraction method converges at first order (measured -10.8 %, -4.6 % at 32, 64 cells, phi 0.2);
  // the sharp treatment is at -0.34 %, -0.05 %: the accuracy gain that justifies it.
  const ArrayResult a = solveArray(0.2, 32, ImmersedMethod::penalized), b = solveArray(0.2, 64, ImmersedMethod::penalized);
  const double ea = a.fstar / 51.53 - 1, eb = b.fstar / 51.53 - 1;
  EXPECT_NEAR(ea / eb, 2.0, 0.5) << ea << " " << eb;
  EXPECT_GT(std::abs(eb), 5 * std::abs(solveArray(0.2, 64, ImmersedMethod::sharp).fstar / 51.53 - 1));
  EXPECT_NEAR(a.force_balance, 1.0, 1e-9);
}

TEST(Array, IterativeSolverAgreesWithDirect) {
  const ArrayResult d = solveArray(0.2, 32, ImmersedMethod::sharp, "direct");
  const ArrayResult i = solveArray(0.2, 32, ImmersedMethod::sharp, "iterative");
  EXPECT_NEAR(i.fstar / d.fstar, 1.0, 1e-6);
}
