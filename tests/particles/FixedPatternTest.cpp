// Re-solves that keep the matrix pattern (SolverOptions::fixed_pattern, MicromodelFlowOptions::
// fixed_pattern): deposits close pixels and thin the aperture, and the kept solver assembles the
// new geometry into the clean chip's pattern (closed faces: identity rows; closed cells: pinned)
// and factorises it numerically with the clean chip's ordering and symbolic analysis.
// Reference: a solver rebuilt for the same geometry (new matrix, ordering, symbolic analysis and
// LU), i.e. the same discrete equations solved by another elimination order. Both are direct LU
// solves, so they differ only by rounding, spread over the whole field (measured: k to 3e-12,
// the velocities to 2.5e-10 of the largest, OpenBLAS). The tolerance 1e-9 (relative, on the flow
// rate and on the velocities over the largest) is 1000 times below the 6 digits the scene writes;
// a wrong identity row, a missing pin or a stencil entry lost in the padding changes the discrete
// equations themselves, which rounding does not. Symbolic factorisations are counted
// with PETSc's own event log (MatLUFactorSym, what -log_view reports). Unit tier, < 1 s each.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>

#include <petsclog.h>

#include "GrainMask.hpp"
#include "mmval/particles/DepositGrid.hpp"
#include "mmval/particles/MicromodelFlow.hpp"
#include "mmval/simulate/FlowSolver.hpp"
#include "mmval/simulate/Geometry.hpp"
#include "mmval/simulate/Grid.hpp"
#include "mmval/simulate/Petsc.hpp"

namespace mmval::particles {
namespace {

constexpr double kPixel = 5e-6, kDepth = 20e-6;
constexpr double kAgree = 1e-9;  ///< fixed pattern against a rebuilt solver (see the header)

/// Symbolic LU factorisations so far in this process (PETSc's event log, started on first use).
int symbolicFactorisations() {
  simulate::PetscSession::ensure();
  PetscBool active = PETSC_FALSE;
  PetscLogIsActive(&active);
  if (!active) PetscLogDefaultBegin();
  PetscLogEvent ev = 0;
  PetscLogEventGetId("MatLUFactorSym", &ev);
  PetscEventPerfInfo info{};
  PetscLogEventGetPerfInfo(0, ev, &info);
  return info.count;
}

PixelMask grains() { return test_support::roundGrains120x60(); }

// rebuild (fixed false): a new solver per solve
MicromodelFlowOptions options(bool fixed) { return test_support::flowOptions(kPixel, kDepth, 1, fixed, fixed); }

void depositSome(DepositGrid& d, const PixelMask& solid, std::mt19937& rng, int n) {
  test_support::depositSome(d, solid, rng, n, kPixel, kDepth);
}

using test_support::velocityDeviation;

TEST(FixedPattern, ReSolvesEqualRebuiltSolvesWithOneSymbolicFactorisation) {
  const PixelMask solid = grains();
  const int before = symbolicFactorisations();
  MicromodelFlow fixed(solid, options(true));
  const FlowSolveResult r0 = fixed.solve({});
  EXPECT_FALSE(r0.pattern_kept);  // the first solve orders and analyses the clean chip
  const int after_first = symbolicFactorisations();
  EXPECT_EQ(after_first - before, 1);
  DepositGrid d(solid, kPixel, kDepth, 0.5);
  std::mt19937 rng(17);
  int kept = 0, symbolic_rebuilt = 0;
  for (int step = 0; step < 4; ++step) {
    depositSome(d, solid, rng, 8);
    ASSERT_GT(d.closedCount(), 0);
    const int s0 = symbolicFactorisations();
    const FlowSolveResult w = fixed.solve(d.closed(), d.aperture());
    const int s1 = symbolicFactorisations();
    MicromodelFlow rebuilt(solid, options(false));
    const FlowSolveResult f = rebuilt.solve(d.closed(), d.aperture());
    symbolic_rebuilt += symbolicFactorisations() - s1;
    ASSERT_FALSE(f.blocked);
    kept += w.pattern_kept ? 1 : 0;
    EXPECT_TRUE(w.pattern_kept) << "re-solve " << step << " did not fit the clean chip's pattern";
    EXPECT_EQ(s1 - s0, 0) << "re-solve " << step << " ordered and analysed the matrix again";
    EXPECT_NEAR(w.permeability, f.permeability, kAgree * f.permeability) << "re-solve " << step;
    EXPECT_LT(w.permeability, r0.permeability);  // deposits only take pore space away
    const double dev = velocityDeviation(fixed, rebuilt);
    EXPECT_LT(dev, kAgree) << "re-solve " << step;
    std::printf("re-solve %d: %lld closed pixels, k %.15g (rebuilt %.15g, rel. diff %.2g), velocity deviation %.2g, %s\n", step,
                static_cast<long long>(d.closedCount()), w.permeability, f.permeability, w.permeability / f.permeability - 1, dev,
                w.pattern_kept ? "kept pattern" : "new solver");
  }
  EXPECT_EQ(kept, 4);
  EXPECT_EQ(symbolicFactorisations() - before - symbolic_rebuilt, 1);  // the fixed-pattern flow's whole life: one analysis
}

/// A 40 x 20 pixel depth-averaged channel, 1 cell per pixel, driven by 1 Pa from west to east, with `closed` pixels.
simulate::FlowProblem channel(const PixelMask& closed) {
  simulate::FlowProblem p = test_support::pressureDrivenChannel40x20(kPixel, kDepth);
  // Closed pixels as the micromodel closes deposit pixels: squares solid on their edges too.
  p.shape = poreShape(PixelMask::Constant(closed.rows(), closed.cols(), false), closed, kPixel);
  return p;
}

TEST(FixedPattern, DisconnectedPocketCarriesNoFlowAndKeepsAFinitePressure) {
  // A ring of closed pixels (rows 5-11, columns 15-23 from the top) walls off a 5 x 7 pixel pocket
  // of fluid in the middle of the channel: the pocket touches no pressure boundary, so the solver
  // pins one of its cells (p = 0); its faces carry nothing (Stokes flow with no drive in a closed
  // box: u = 0 exactly). The flow around it must equal a rebuilt solver's.
  PixelMask none = PixelMask::Constant(20, 40, false), ring = none;
  for (int r = 5; r <= 11; ++r)
    for (int c = 15; c <= 23; ++c) ring(r, c) = r == 5 || r == 11 || c == 15 || c == 23;
  simulate::SolverOptions so;
  so.keep_factorisation = true;
  so.fixed_pattern = true;
  simulate::SteadyFlowSolver fixed(channel(none), so);
  EXPECT_FALSE(fixed.solve().pattern_kept);  // the first solve orders and analyses
  const double q0 = fixed.flowRate(simulate::Side::east);
  const int s0 = symbolicFactorisations();
  fixed.update(channel(ring));
  const simulate::FlowStats& st = fixed.solve();
  EXPECT_TRUE(st.pattern_kept);
  EXPECT_EQ(symbolicFactorisations() - s0, 0);
  simulate::SteadyFlowSolver rebuilt(channel(ring));
  rebuilt.solve();
  const double q = fixed.flowRate(simulate::Side::east), qr = rebuilt.flowRate(simulate::Side::east);
  EXPECT_GT(q, 0);
  EXPECT_LT(q, q0);  // the ring narrows the channel
  EXPECT_NEAR(q, qr, kAgree * qr);
  EXPECT_NEAR(fixed.flowRate(simulate::Side::west), q, kAgree * q);  // mass conservation through the channel
  const Eigen::ArrayXXd &u = fixed.u(), &v = fixed.v(), &p = fixed.p();
  const double umax = std::max(u.abs().maxCoeff(), v.abs().maxCoeff());
  EXPECT_LT((u - rebuilt.u()).abs().maxCoeff(), kAgree * umax);
  EXPECT_LT((v - rebuilt.v()).abs().maxCoeff(), kAgree * umax);
  EXPECT_TRUE(p.isFinite().all());
  EXPECT_TRUE(u.isFinite().all() && v.isFinite().all());
  // The pocket (rows 6-10 from the top are cells j = 9..13 from the bottom; columns 16-22), faces inside it included.
  double pocket = 0;
  for (int j = 9; j <= 13; ++j)
    for (int i = 16; i <= 23; ++i) pocket = std::max(pocket, std::abs(u(j, i)));
  for (int j = 9; j <= 14; ++j)
    for (int i = 16; i <= 22; ++i) pocket = std::max(pocket, std::abs(v(j, i)));
  EXPECT_LT(pocket, 1e-12 * umax) << "flow inside the walled-off pocket";
  std::printf("channel: q %.15g (rebuilt %.15g), pocket |u| max %.2g of the largest\n", q, qr, pocket / umax);
}

}  // namespace
}  // namespace mmval::particles
