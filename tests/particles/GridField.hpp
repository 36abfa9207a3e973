// Test fields on a node grid 10 um apart: uniform flow along x in the fluid, zero in
// solid nodes, constant depth, solid where `solid(i, j)` says (the LIGGGHTS tests'
// grains and walls).
#pragma once
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "mmval/particles/FlowField.hpp"

namespace mmval::particles::test_support {

inline std::shared_ptr<GriddedFlow> gridField(int nx, int ny, double ux, double depth, const std::function<bool(int, int)>& solid) {
  auto g = std::make_shared<GriddedFlow>(nx, ny, 0, 0, 10e-6, 10e-6);
  const auto n = static_cast<std::size_t>(nx) * ny;
  std::vector<double> u(n, ux), v(n, 0.0), h(n, depth);
  std::vector<std::uint8_t> s(n, 0);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i)
      if (solid(i, j)) {
        const auto k = static_cast<std::size_t>(j) * nx + i;
        s[k] = 1;
        u[k] = 0;
      }
  g->update(u, v, h, s);
  return g;
}

}  // namespace mmval::particles::test_support
