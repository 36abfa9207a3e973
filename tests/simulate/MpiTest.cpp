// Runs under `mpiexec -n 2` (ctest: simulate_mpi_np2; rank count 2): the
// distributed solve (MUMPS over PETSC_COMM_WORLD) must give the 1-rank answer
// (each rank also solves alone on MPI_COMM_SELF) to solver tolerance.
#include <cmath>
#include <cstdio>
#include <memory>

#include <gtest/gtest.h>
#include <petscsys.h>  // PetscOptionsSetValue

#include "mmval/simulate/FlowSolver.hpp"
#include "mmval/simulate/Geometry.hpp"
#include "mmval/simulate/Petsc.hpp"
#include "mmval/simulate/ResolvedStokes.hpp"
#include "mmval/simulate/UnsteadyFlowSolver.hpp"

using namespace mmval::simulate;

namespace {

FlowProblem cylinderProblem() {
  const double H = 0.41, Um = 0.3, h = 0.01;
  FlowProblem p;
  p.x = refinedAxis(0, 2.2, 0.125, 0.35, h, 1.1, 4 * h);
  p.y = refinedAxis(0, H, 0.125, 0.275, h, 1.1, 4 * h);
  p.boundary[0].type = BoundaryType::velocity;
  p.boundary[0].velocity = [=](double y) { return 4 * Um * y * (H - y) / (H * H); };
  p.boundary[1].type = BoundaryType::pressure;
  p.density = 1;
  p.viscosity = 1e-3;
  p.inertia = true;
  p.shape = std::make_shared<Circles>(std::vector<Circle>{{0.2, 0.2, 0.05}});
  return p;
}

constexpr double kCellSide = 1e-4;  ///< m

/// A periodic cell of side kCellSide on n x n cells with discs as grains, driven by a body force.
FlowProblem periodicCell(int n, Eigen::Vector2d force, std::vector<Circle> discs) {
  FlowProblem p;
  p.x = uniformAxis(0, kCellSide, n);
  p.y = uniformAxis(0, kCellSide, n);
  for (auto& b : p.boundary) b.type = BoundaryType::periodic;
  p.body_force = force;
  p.shape = std::make_shared<Circles>(std::move(discs), kCellSide, kCellSide);
  return p;
}

}  // namespace

TEST(Mpi, TwoRanksGiveTheOneRankAnswer) {
  PetscSession::ensure();
  SteadyFlowSolver serial(cylinderProblem(), {}, MPI_COMM_SELF);
  serial.solve();
  SteadyFlowSolver parallel(cylinderProblem(), {}, MPI_COMM_WORLD);
  parallel.solve();
  const double a = serial.bodyLoads()[0].force.x(), b = parallel.bodyLoads()[0].force.x();
  if (PetscSession::rank() == 0) std::printf("steady 1 vs %d ranks: drag ratio - 1 = %.3e\n", PetscSession::size(), b / a - 1);
  EXPECT_NEAR(b / a, 1.0, 1e-8) << "ranks " << PetscSession::size();
  EXPECT_NEAR((parallel.u() - serial.u()).abs().maxCoeff(), 0.0, 1e-9);
}

TEST(Mpi, TwoRanksGiveTheOneRankUnsteadySteps) {
  // 20 BDF2 steps of the 2D-2 flow (U_max 1.5 m/s) from rest on a coarse grid. Each step solves to
  // GMRES tolerance 1e-10 (lagged LU preconditioner; MUMPS in parallel, UMFPACK serial), so the
  // histories agree to ~1e-9 relative; 1e-7 leaves room for 20 steps of accumulation.
  PetscSession::ensure();
  FlowProblem p = cylinderProblem();
  p.boundary[0].velocity = [](double y) { return 4 * 1.5 * y * (0.41 - y) / (0.41 * 0.41); };
  p.x = refinedAxis(0, 1.0, 0.125, 0.5, 0.02, 1.1, 0.06);
  p.y = refinedAxis(0, 0.41, 0.125, 0.275, 0.02, 1.1, 0.06);
  UnsteadyFlowSolver serial(p, {}, {}, MPI_COMM_SELF), parallel(p, {}, {}, MPI_COMM_WORLD);
  double worst = 0;
  for (int k = 0; k < 20; ++k) {
    const double a = serial.step(5e-3), b = parallel.step(5e-3);
    ASSERT_NEAR(a, b, 1e-15);
    const double fa = serial.bodyLoads()[0].force.x(), fb = parallel.bodyLoads()[0].force.x();
    worst = std::max(worst, std::abs(fb / fa - 1));
  }
  if (PetscSession::rank() == 0) std::printf("unsteady 1 vs %d ranks: max relative drag difference over 20 steps %.3e\n", PetscSession::size(), worst);
  EXPECT_LT(worst, 1e-7) << "ranks " << PetscSession::size();
  Eigen::ArrayXXd us, vs, ps, up, vp, pp;
  serial.fields(us, vs, ps);
  parallel.fields(up, vp, pp);
  EXPECT_LT((up - us).abs().maxCoeff() / us.abs().maxCoeff(), 1e-7);
}

TEST(Mpi, TwoRanksIterativeStokesGiveTheOneRankDirectAnswer) {
  // Periodic square array (phi 0.2, 48 cells): FGMRES + fieldsplit (BoomerAMG, mass-matrix Schur)
  // on 2 ranks against serial LU. Relative tolerance 1e-10 on the residual; 1e-7 on the flux.
  PetscSession::ensure();
  const double L = kCellSide;
  const FlowProblem p = periodicCell(48, {1.0, 0}, {{0.5 * L, 0.5 * L, L * std::sqrt(0.2 / M_PI)}});
  SolverOptions it;
  it.linear = "iterative";
  SteadyFlowSolver serial(p, {}, MPI_COMM_SELF), parallel(p, it, MPI_COMM_WORLD);
  serial.solve();
  parallel.solve();
  const double a = serial.superficialVelocity(), b = parallel.superficialVelocity();
  if (PetscSession::rank() == 0) std::printf("iterative Stokes on %d ranks vs serial LU: Darcy velocity ratio - 1 = %.3e\n", PetscSession::size(), b / a - 1);
  EXPECT_NEAR(b / a, 1.0, 1e-7);
}

TEST(Mpi, TwoRanksIterativeDepthAveragedGiveTheOneRankDirectAnswer) {
  // Depth-averaged Stokes through a mask of disc grains with a varying aperture (the micromodel's
  // friction split: GMRES, Gauss-Seidel on the velocity block, MUMPS LU of B diag(A)^-1 B^T) on 2
  // ranks, whose rows are laid out in bands of cell rows with their u, v and p unknowns, against
  // the serial LU. Residual 1e-12 of the right-hand side; the flow rate within 1e-9, the
  // velocities within 1e-8 of the largest (as the serial split test, SplitSolveTest.cpp).
  PetscSession::ensure();
  constexpr int nx = 64, ny = 40;
  constexpr double px = 10e-6, depth = 20e-6;
  Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic> solid = Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic>::Constant(ny, nx, false);
  const double grains[][3] = {{20, 12, 5}, {34, 28, 6}, {46, 10, 4}, {27, 33, 3}, {50, 25, 5}};
  for (const auto& g : grains)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) solid(j, i) = solid(j, i) || std::hypot(i + 0.5 - g[0], j + 0.5 - g[1]) < g[2];
  FlowProblem p;
  p.x = uniformAxis(0, nx * px, nx);
  p.y = uniformAxis(0, ny * px, ny);
  p.boundary[0].type = p.boundary[1].type = BoundaryType::pressure;
  p.boundary[0].pressure = 1.0;
  p.boundary[2].type = p.boundary[3].type = BoundaryType::no_slip;
  p.viscosity = 1e-3;
  p.depth = depth;
  p.depth_field = Eigen::ArrayXXd::Constant(ny, nx, depth);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i)
      if ((i * 7 + j * 3) % 5 == 0) p.depth_field(j, i) = (0.4 + 0.1 * ((i + j) % 6)) * depth;  // thinned apertures
  p.shape = std::make_shared<MaskShape>(solid, px);
  SolverOptions it;
  it.linear = "iterative";
  it.linear_rtol = 1e-12;
  SteadyFlowSolver serial(p, {}, MPI_COMM_SELF), parallel(p, it, MPI_COMM_WORLD);
  serial.solve();
  const FlowStats& s = parallel.solve();
  EXPECT_EQ(s.linear_solver, "iterative");
  EXPECT_FALSE(s.linear_fallback);
  const double a = serial.superficialVelocity(), b = parallel.superficialVelocity();
  const double umax = std::max(serial.u().abs().maxCoeff(), serial.v().abs().maxCoeff());
  const double dev = std::max((parallel.u() - serial.u()).abs().maxCoeff(), (parallel.v() - serial.v()).abs().maxCoeff()) / umax;
  if (PetscSession::rank() == 0)
    std::printf("depth-averaged split on %d ranks vs serial LU: flow ratio - 1 = %.3e, velocity deviation %.3e of the largest, %d iterations\n",
                PetscSession::size(), b / a - 1, dev, s.linear_iterations);
  EXPECT_GT(a, 0.0);
  EXPECT_NEAR(b / a, 1.0, 1e-9);
  EXPECT_LT(dev, 1e-8);
}

TEST(Mpi, TwoRanksGiveTheOneRankParticleMobility) {
  // Resolved particles: two free cylinders near a fixed one in a channel flow, the mobility problem
  // (7 solves on one factorisation each way) on 1 and on 2 ranks.
  PetscSession::ensure();
  FlowProblem p;
  const double W = 40e-6;
  p.x = uniformAxis(0, 100e-6, 100);
  p.y = uniformAxis(0, W, 40);
  p.boundary[0].type = BoundaryType::velocity;
  p.boundary[0].velocity = [=](double y) { return 6 * 1e-4 * y * (W - y) / (W * W); };
  p.boundary[1].type = BoundaryType::pressure;
  p.shape = std::make_shared<Circles>(std::vector<Circle>{{50e-6, 20e-6, 8e-6}, {30e-6, 14e-6, 5e-6}, {32e-6, 29e-6, 5e-6}});
  ResolvedStokes serial(p, {}, MPI_COMM_SELF), parallel(p, {}, MPI_COMM_WORLD);
  const std::vector<BodyLoad> ext(3);
  const std::vector<bool> free = {false, true, true};
  const MobilityResult a = serial.freeMotion(ext, free), b = parallel.freeMotion(ext, free);
  for (int k = 1; k < 3; ++k) {
    const auto& A = a.motion[static_cast<std::size_t>(k)];
    const auto& B = b.motion[static_cast<std::size_t>(k)];
    if (PetscSession::rank() == 0)
      std::printf("mobility 1 vs %d ranks, body %d: U (%.6e, %.6e) vs (%.6e, %.6e)\n", PetscSession::size(), k, A.velocity.x(), A.velocity.y(),
                  B.velocity.x(), B.velocity.y());
    EXPECT_NEAR((B.velocity - A.velocity).norm() / A.velocity.norm(), 0.0, 1e-8);
    EXPECT_NEAR(B.spin, A.spin, 1e-8 * std::abs(A.spin) + 1e-12);
  }
  EXPECT_GT(a.motion[1].velocity.x(), 0.0);  // carried downstream
}

TEST(Mpi, TwoRanksPreconditionTheVelocityBlockOneComponentPerRank) {
  // Plane Stokes, iterative, on 2 ranks: the velocity block is preconditioned one component per
  // rank (rank 0 u, rank 1 v, a serial BoomerAMG each; ComponentSplit.hpp). Under a constant
  // viscosity u and v do not couple in the block, so the preconditioner is the same operator as
  // one BoomerAMG over both components up to the hierarchy's coarsening: the answer must be the
  // serial LU's (1e-7 on the Darcy velocity, as above) and the GMRES count within 2 of the
  // one-rank iterative solve's. With the option off, the block's BoomerAMG runs on both ranks and
  // gives the same answer. Grain: a disc off the cell centres and an ellipse-like pair of discs,
  // so that the u and v cut-cell rows differ.
  PetscSession::ensure();
  const double L = kCellSide;
  const FlowProblem p = periodicCell(80, {0.7, 0.3}, {{0.43 * L, 0.52 * L, 0.21 * L}, {0.61 * L, 0.37 * L, 0.12 * L}});
  SolverOptions it;
  it.linear = "iterative";
  SteadyFlowSolver lu(p, {}, MPI_COMM_SELF), one(p, it, MPI_COMM_SELF), two(p, it, MPI_COMM_WORLD);
  lu.solve();
  const FlowStats s1 = one.solve();
  const FlowStats s2 = two.solve();
  PetscOptionsSetValue(nullptr, "-fluidm_fieldsplit_0_by_component", "0");
  SteadyFlowSolver block(p, it, MPI_COMM_WORLD);
  const FlowStats sb = block.solve();
  PetscOptionsClearValue(nullptr, "-fluidm_fieldsplit_0_by_component");
  // A user's own choice of the block's preconditioner is kept (the split does not replace it) and
  // recorded as the user's.
  PetscOptionsSetValue(nullptr, "-fluidm_fieldsplit_0_pc_type", "gamg");
  SteadyFlowSolver chosen(p, it, MPI_COMM_WORLD);
  const FlowStats sc = chosen.solve();
  PetscOptionsSetValue(nullptr, "-fluidm_fieldsplit_0_pc_type", "hypre");  // back to the solver's default
  EXPECT_EQ(sc.velocity_preconditioner, "-fluidm_fieldsplit_0_pc_type gamg (the user's)");
  EXPECT_NEAR(chosen.superficialVelocity() / lu.superficialVelocity(), 1.0, 1e-7);
  const double a = lu.superficialVelocity();
  if (PetscSession::rank() == 0)
    std::printf("velocity block on %d ranks by component: %d iterations (one rank %d, block AMG on 2 ranks %d), Darcy velocity ratio - 1 = %.3e\n",
                PetscSession::size(), s2.linear_iterations, s1.linear_iterations, sb.linear_iterations, two.superficialVelocity() / a - 1);
  EXPECT_EQ(s1.velocity_preconditioner, "BoomerAMG on the velocity block");
  EXPECT_EQ(s2.velocity_preconditioner, "by component: rank 0 u, rank 1 v, a serial BoomerAMG each");
  EXPECT_EQ(sb.velocity_preconditioner, "BoomerAMG on the velocity block");
  EXPECT_NEAR(two.superficialVelocity() / a, 1.0, 1e-7);
  EXPECT_NEAR(block.superficialVelocity() / a, 1.0, 1e-7);
  EXPECT_LE(std::abs(s2.linear_iterations - s1.linear_iterations), 2);
  EXPECT_LT(s2.linear_true_residual, 1e-8);
}
