// The Schaefer-Turek channel (0.41 high, a cylinder of D = 0.1 at (0.2, 0.2), parabolic inflow of
// peak Umax, pressure outlet) on a grid refined to cells of h about the cylinder, for the unsteady tests.
#pragma once
#include <memory>
#include <vector>

#include "mmval/simulate/FlowSolver.hpp"
#include "mmval/simulate/Geometry.hpp"
#include "mmval/simulate/Grid.hpp"

namespace mmval::test {

inline simulate::FlowProblem cylinderChannelProblem(double Umax, double h, double length) {
  using namespace mmval::simulate;
  const double H = 0.41, D = 0.1;
  FlowProblem p;
  p.x = refinedAxis(0, length, 0.125, 0.5, h, 1.1, 3 * h);
  p.y = refinedAxis(0, H, 0.08, 0.32, h, 1.1, 3 * h);
  p.boundary[0].type = BoundaryType::velocity;
  p.boundary[0].velocity = [=](double y) { return 4 * Umax * y * (H - y) / (H * H); };
  p.boundary[1].type = BoundaryType::pressure;
  p.density = 1;
  p.viscosity = 1e-3;
  p.shape = std::make_shared<Circles>(std::vector<Circle>{{0.2, 0.2, 0.5 * D}});
  return p;
}

}  // namespace mmval::test
