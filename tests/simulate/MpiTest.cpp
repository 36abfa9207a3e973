// Runs under `mpiexec -n 2` (ctest: simulate_mpi_np2; rank count 2): the
// distributed solve (MUMPS over PETSC_COMM_WORLD) must give the 1-rank answer
// (each rank also solves alone on MPI_COMM_SELF) to solver tolerance.
#include <cmath>
#include <memory>

#include <gtest/gtest.h>

#include "mmval/simulate/FlowSolver.hpp"
#include "mmval/simulate/Petsc.hpp"

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

}  // namespace

TEST(Mpi, TwoRanksGiveTheOneRankAnswer) {
  PetscSession::ensure();
  SteadyFlowSolver serial(cylinderProblem(), {}, MPI_COMM_SELF);
  serial.solve();
  SteadyFlowSolver parallel(cylinderProblem(), {}, MPI_COMM_WORLD);
  parallel.solve();
  const double a = serial.bodyLoads()[0].force.x(), b = parallel.bodyLoads()[0].force.x();
  EXPECT_NEAR(b / a, 1.0, 1e-8) << "ranks " << PetscSession::size();
  EXPECT_NEAR((parallel.u() - serial.u()).abs().maxCoeff(), 0.0, 1e-9);
}
