// What the micromodel flow tests share (WarmResolveTest, FixedPatternTest): a small mask,
// deposits placed as the scene makes them, and the velocity difference the engines would see.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <random>

#include "mmval/particles/DepositGrid.hpp"
#include "mmval/particles/MicromodelFlow.hpp"
#include "mmval/simulate/FlowSolver.hpp"
#include "mmval/simulate/Grid.hpp"

namespace mmval::particles::test_support {

/// 120 x 60 pixels with five round grains (none touches the inlet or outlet column).
inline PixelMask roundGrains120x60() {
  PixelMask m = PixelMask::Constant(60, 120, false);
  const double c[][3] = {{25, 15, 8}, {50, 40, 10}, {80, 18, 9}, {100, 45, 7}, {60, 10, 5}};
  for (int r = 0; r < m.rows(); ++r)
    for (int col = 0; col < m.cols(); ++col)
      for (const auto& g : c) m(r, col) = m(r, col) || std::hypot(col - g[0], r - g[1]) < g[2];
  return m;
}

/// Deposits as the scene makes them: column deposits (1.5 pixel columns of volume, closing the
/// pixel) and plate layers (monolayer patches of 3 um particles) at random pore pixels, `n` of each.
inline void depositSome(DepositGrid& d, const PixelMask& solid, std::mt19937& rng, int n, double pixel, double depth) {
  std::uniform_int_distribution<int> col(2, static_cast<int>(solid.cols()) - 3), row(0, static_cast<int>(solid.rows()) - 1);
  const double column = pixel * pixel * depth;
  for (int placed = 0; placed < 2 * n;) {
    const int c = col(rng), r = row(rng);
    if (solid(r, c) || d.closed()(r, c)) continue;
    const double x = (c + 0.5) * pixel, y = (static_cast<double>(solid.rows()) - 1 - r + 0.5) * pixel;
    if (placed % 2 == 0) d.add(x, y, 1.5 * column);
    else d.addLayer(x, y, 3.0 * column, 3e-6);
    ++placed;
  }
}

/// Largest velocity difference over the largest velocity, on the node arrays the engines see.
inline double velocityDeviation(const MicromodelFlow& a, const MicromodelFlow& b) {
  double dmax = 0, umax = 0;
  for (std::size_t k = 0; k < a.nodeUx().size(); ++k) {
    dmax = std::max({dmax, std::abs(a.nodeUx()[k] - b.nodeUx()[k]), std::abs(a.nodeUy()[k] - b.nodeUy()[k])});
    umax = std::max({umax, std::abs(b.nodeUx()[k]), std::abs(b.nodeUy()[k])});
  }
  return dmax / umax;
}

/// A 40 x 20 cell depth-averaged channel of square cells `cell` wide and `depth` deep, driven by
/// 1 Pa from west to east between no-slip sides, sharp immersed boundary, no shape yet.
inline simulate::FlowProblem pressureDrivenChannel40x20(double cell, double depth) {
  simulate::FlowProblem p;
  p.x = simulate::uniformAxis(0, 40 * cell, 40);
  p.y = simulate::uniformAxis(0, 20 * cell, 20);
  p.boundary[0].type = p.boundary[1].type = simulate::BoundaryType::pressure;
  p.boundary[0].pressure = 1.0;
  p.boundary[2].type = p.boundary[3].type = simulate::BoundaryType::no_slip;
  p.depth = depth;
  p.method = simulate::ImmersedMethod::sharp;
  return p;
}

/// Micromodel flow options for the tests: `pixel` x `depth` pixels at a Darcy velocity of
/// 1e-4 m/s and `cells_per_pixel`, warm re-solves and the kept pattern as given.
inline MicromodelFlowOptions flowOptions(double pixel, double depth, double cells_per_pixel, bool warm_start, bool fixed_pattern) {
  MicromodelFlowOptions o;
  o.pixel = pixel;
  o.depth = depth;
  o.darcy_velocity = 1e-4;
  o.cells_per_pixel = cells_per_pixel;
  o.warm_start = warm_start;
  o.fixed_pattern = fixed_pattern;
  return o;
}

}  // namespace mmval::particles::test_support
