// The particle side's cost near walls: GriddedFlow (GridWalls::brinkman, the micromodel scene's
// field) on a pixel grid of disc grains, evaluated at points spread over the pore space and at
// points within the match distance of a wall (the Brinkman layer's slot search). Google
// Benchmark; never asserts on time.
//   bench_particles_near_wall [--benchmark_filter=...]
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <vector>

#include "mmval/particles/FlowField.hpp"

using namespace mmval::particles;

namespace {

constexpr double kPixel = 10e-6, kDepth = 20e-6;

/// 200 x 150 pixels (the default scene's window) of discs 3-9 pixels in radius on a jittered
/// lattice, a uniform face velocity in the pore space, 10 um resolved (one cell per pixel).
struct Scene {
  int nx = 202, ny = 152;
  GriddedFlow flow{nx, ny, -0.5 * kPixel, -0.5 * kPixel, kPixel, kPixel, GridWalls::brinkman, kPixel};
  std::vector<std::uint8_t> solid;
  std::vector<double> ux, uy, h;
  std::vector<Vec2> pore, near_wall;

  Scene() {
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    const auto n = static_cast<std::size_t>(nx) * ny;
    solid.assign(n, 0);
    ux.assign(n, 4e-4);
    uy.assign(n, 0.0);
    h.assign(n, kDepth);
    for (int i = 0; i < nx; ++i) solid[i] = solid[static_cast<std::size_t>(ny - 1) * nx + i] = 1;  // side walls
    for (int cy = 10; cy < ny; cy += 20)
      for (int cx = 10; cx < nx; cx += 20) {
        const double x0 = cx + 6 * (uni(rng) - 0.5), y0 = cy + 6 * (uni(rng) - 0.5), r = 3 + 6 * uni(rng);
        for (int j = 0; j < ny; ++j)
          for (int i = 0; i < nx; ++i)
            if (std::hypot(i - x0, j - y0) <= r) solid[static_cast<std::size_t>(j) * nx + i] = 1;
      }
    flow.update(ux, uy, h, solid);
    const double d_m = flow.matchDistance(kDepth);
    while (pore.size() < 4096 || near_wall.size() < 4096) {
      const double x = uni(rng) * (nx - 2) * kPixel, y = uni(rng) * (ny - 2) * kPixel;
      if (flow.isSolid(x, y)) continue;
      if (pore.size() < 4096) pore.emplace_back(x, y);
      if (near_wall.size() < 4096 && flow.wallDistance(x, y) < d_m) near_wall.emplace_back(x, y);
    }
  }
};

const Scene& scene() {
  static const Scene s;
  return s;
}

void evaluate(benchmark::State& state, const std::vector<Vec2>& points, int what) {
  const GriddedFlow& f = scene().flow;
  std::size_t k = 0;
  for (auto _ : state) {
    const Vec2& p = points[k++ % points.size()];
    if (what == 0) benchmark::DoNotOptimize(f.meanVelocity(p.x(), p.y()));
    else benchmark::DoNotOptimize(f.wallDistance(p.x(), p.y()));
  }
}

void BM_MeanVelocityPore(benchmark::State& s) { evaluate(s, scene().pore, 0); }
void BM_MeanVelocityNearWall(benchmark::State& s) { evaluate(s, scene().near_wall, 0); }
void BM_WallDistancePore(benchmark::State& s) { evaluate(s, scene().pore, 1); }

void BM_Update(benchmark::State& state) {
  // A re-solve's field update (distance transform, wall cells and their per-node lists).
  const Scene& sc = scene();
  GriddedFlow f(sc.nx, sc.ny, -0.5 * kPixel, -0.5 * kPixel, kPixel, kPixel, GridWalls::brinkman, kPixel);
  for (auto _ : state) f.update(sc.ux, sc.uy, sc.h, sc.solid);
}

}  // namespace

BENCHMARK(BM_MeanVelocityPore);
BENCHMARK(BM_MeanVelocityNearWall);
BENCHMARK(BM_WallDistancePore);
BENCHMARK(BM_Update)->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
