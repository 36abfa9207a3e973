// Pressure Poisson solve on the MAC grid's cells: div (grad p) = f with
// zero-flux sides (or periodic), the operator of a projection step. Solved
// with PETSc CG + GAMG (algebraic multigrid), whose cost grows ~O(N): this
// is the O(N) building block the unsteady projection solver and the
// benchmark use. The pure-Neumann null space (constants) is removed.
#pragma once
#include <memory>

#include <Eigen/Core>
#include <mpi.h>

#include "mmval/simulate/Grid.hpp"

namespace mmval::simulate {

struct PoissonStats {
  long long unknowns = 0;
  int iterations = 0;
  double setup_seconds = 0, solve_seconds = 0;
  double residual = 0;  ///< final relative residual
};

class PressurePoisson {
 public:
  /// Assembles the 5-point finite-volume Laplacian on x by y cells (periodic
  /// along an axis if the flag is set); `rtol` is the relative residual target.
  PressurePoisson(Axis x, Axis y, bool periodic_x, bool periodic_y, double rtol = 1e-8, MPI_Comm comm = MPI_COMM_WORLD);
  ~PressurePoisson();
  PressurePoisson(const PressurePoisson&) = delete;
  PressurePoisson& operator=(const PressurePoisson&) = delete;
  /// Solves for p (ny x nx) given the cell source f (ny x nx, its mean is removed).
  Eigen::ArrayXXd solve(const Eigen::ArrayXXd& f);
  const PoissonStats& stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> m;
};

}  // namespace mmval::simulate
