// Resolved particles: cost against error of one mobility solve (ResolvedStokes::freeMotion) for
// a cylinder settling midway between plates (a/l = 0.25) against Faxen's series, over cells per
// diameter. One row per grid: unknowns, Stokes solves, factorisations, wall time of the mobility
// problem (geometry, one factorisation, 4 solves), velocity error. Never asserts on time.
//   bench_simulate_resolved [cells_per_diameter ...]   (default 8 12 16 24 32)
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <vector>

#include <fmt/format.h>

#include "mmval/simulate/Petsc.hpp"
#include "mmval/simulate/ResolvedStokes.hpp"

using namespace mmval::simulate;

int main(int argc, char** argv) {
  PetscSession::ensure();
  std::vector<int> per;
  for (int a = 1; a < argc; ++a) per.push_back(std::atoi(argv[a]));
  if (per.empty()) per = {8, 12, 16, 24, 32};
  const double l = 20e-6, a = 0.25 * l, mu = 1e-3, F = 1e-8;  // F: weight per unit length, N/m
  const double faxen = F / faxenCylinderResistance(a, l, mu);
  fmt::print("cylinder settling midway between plates, a/l = 0.25, box 10 l long: one mobility solve vs cells per diameter\n");
  fmt::print("{:>6} {:>9} {:>7} {:>8} {:>9} {:>12} {:>10}\n", "cells/d", "unknowns", "solves", "factors", "wall s", "U/U_faxen", "error %");
  for (int n : per) {
    const double h = 2 * a / n;
    FlowProblem p;
    p.x = uniformAxis(-5 * l, 5 * l, static_cast<int>(std::lround(10 * l / h)));
    p.y = uniformAxis(-l, l, static_cast<int>(std::lround(2 * l / h)));
    p.viscosity = mu;
    const auto t0 = std::chrono::steady_clock::now();
    ResolvedStokes s(p);
    s.setShape(std::make_shared<Circles>(std::vector<Circle>{{0, 0, a}}));
    const MobilityResult r = s.freeMotion({BodyLoad{{F, 0}, 0}}, {true});
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const double ratio = r.motion[0].velocity.x() / faxen;
    fmt::print("{:>6} {:>9} {:>7} {:>8} {:>9.3f} {:>12.5f} {:>+10.3f}\n", n, s.stats().unknowns, r.solves, r.factorisations, wall, ratio, 100 * (ratio - 1));
  }
  return 0;
}
