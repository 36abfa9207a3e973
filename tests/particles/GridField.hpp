// Test fields on a node grid 10 um apart: uniform flow along x in the fluid, zero in
// solid nodes, constant depth, solid where `solid(i, j)` says (the LIGGGHTS tests'
// grains and walls).
#pragma once
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "mmval/particles/FlowField.hpp"
#include "mmval/particles/Scene.hpp"

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

/// Where a lattice puts particles of `diameter` in the pore space: x from one radius to x_max in
/// steps dx, y from y_min + a radius to y_max - a radius in steps dy, at two heights (`gap` above
/// the bottom plate and below the top, the channel `depth` deep), each kept where
/// insertionProblem allows it beside those already kept; up to `n` (the engine-thread tests' starts).
struct Lattice {
  double dx, dy, x_max, y_min, y_max, gap;
};
inline std::vector<Vec3> latticeStarts(const FlowField& flow, std::size_t n, double diameter, double depth, const Lattice& l) {
  std::vector<Vec3> xs;
  std::vector<ParticleState> placed;
  const double a = 0.5 * diameter;
  for (double x = 2 * a; x < l.x_max && xs.size() < n; x += l.dx)
    for (double y = l.y_min + a; y < l.y_max - a && xs.size() < n; y += l.dy)
      for (const double z : {a + l.gap, depth - a - l.gap}) {
        const Vec3 p(x, y, z);
        if (xs.size() >= n || !insertionProblem(flow, a, p, placed).empty()) continue;
        ParticleState s;
        s.x = p;
        placed.push_back(s);
        xs.push_back(p);
      }
  return xs;
}

}  // namespace mmval::particles::test_support
