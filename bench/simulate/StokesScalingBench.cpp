// Steady Stokes permeability solve against N: the periodic square array at
// phi = 0.2 (sharp immersed boundary) solved with the iterative coupled solver
// (FGMRES + Schur fieldsplit, GAMG on the velocity block and on the selfp
// Schur approximation) and, for comparison, with the direct LU. Prints one row
// per grid: unknowns, setup+solve time, FGMRES iterations, time per unknown,
// and F* against Sangani & Acrivos (51.53), so the cost is read next to the
// error. Run under mpirun -np 2 as well. Never asserts on time.
//   bench_simulate_stokes_scaling [n1 n2 ...]   (cells per side; default 64 128 256 512)
#include <cmath>
#include <cstdlib>
#include <memory>
#include <vector>

#include <fmt/format.h>

#include "mmval/simulate/FlowSolver.hpp"
#include "mmval/simulate/Petsc.hpp"

using namespace mmval::simulate;

int main(int argc, char** argv) {
  PetscSession::ensure();
  std::vector<int> sizes;
  for (int a = 1; a < argc; ++a) sizes.push_back(std::atoi(argv[a]));
  if (sizes.empty()) sizes = {64, 128, 256, 512};
  const double L = 1e-4, mu = 1e-3, G = 1.0, phi = 0.2;
  if (PetscSession::rank() == 0)
    fmt::print("square array phi 0.2, sharp, {} rank(s): steady Stokes solve time vs N\n{:>6} {:>10} {:>10} {:>9} {:>6} {:>10} {:>9} {:>10}\n",
               PetscSession::size(), "solver", "cells", "unknowns", "solve s", "its", "us/unknown", "F*", "error %");
  for (const std::string linear : {"iterative", "direct"})
    for (int n : sizes) {
      if (linear == "direct" && n > 256) continue;  // LU fill grows ~N log N in memory and faster in time
      FlowProblem p = squareArrayProblem(L, n, phi, mu, G);
      SolverOptions o;
      o.linear = linear;
      o.linear_rtol = 1e-8;
      SteadyFlowSolver s(p, o);
      const FlowStats& st = s.solve();
      const double fstar = G * L * L / (mu * s.superficialVelocity());
      if (PetscSession::rank() == 0)
        fmt::print("{:>6} {:>10} {:>10} {:>9.3f} {:>6} {:>10.3f} {:>9.4f} {:>+10.4f}\n", linear, st.cells, st.unknowns, st.solve_seconds, st.linear_iterations,
                   1e6 * st.solve_seconds / static_cast<double>(st.unknowns), fstar, 100 * (fstar / 51.53 - 1));
    }
  return 0;
}
