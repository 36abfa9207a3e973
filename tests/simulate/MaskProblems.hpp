#pragma once
// Small pixel-mask flow problems shared by the Schur-switch and true-residual tests.

#include <memory>

#include <Eigen/Core>

#include "mmval/simulate/FlowSolver.hpp"
#include "mmval/simulate/Geometry.hpp"

namespace mmval::simulate::mask_problems {

using Mask = Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic>;

/// n x n px mask, pressure from west to east, slip north and south, 1 cell per pixel.
inline FlowProblem maskProblem(const Mask& solid) {
  const double px = 1e-5;
  const int n = static_cast<int>(solid.rows());
  FlowProblem p;
  p.x = uniformAxis(0, n * px, n);
  p.y = uniformAxis(0, n * px, n);
  p.boundary[0].type = p.boundary[1].type = BoundaryType::pressure;
  p.boundary[0].pressure = 1.0;
  p.boundary[2].type = p.boundary[3].type = BoundaryType::slip;
  p.shape = std::make_shared<MaskShape>(solid, px);
  return p;
}

/// Dense: 9 x 9 px square grains on a 12 px pitch, staggered by half a pitch every other row:
/// 3 px throats everywhere, porosity ~0.44 (the generated chip2 mask: 3 px throats, 0.48). The
/// mass-matrix Schur stage stalls on it and the solve switches to selfp.
inline Mask denseThroats(int n) {
  Mask m = Mask::Constant(n, n, false);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const int shift = ((j + 1) / 12) % 2 == 1 ? 6 : 0;
      const int a = (i + 1 + shift) % 12, b = (j + 1) % 12;
      m(i, j) = a >= 3 && b >= 3;
    }
  return m;
}

}  // namespace mmval::simulate::mask_problems
