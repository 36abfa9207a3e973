// Flow fields: exact answers for analytic fields, interpolation exact for linear data.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "mmval/particles/FlowField.hpp"

namespace mmval::particles {
namespace {

TEST(FlowField, PoiseuilleProfileHasMeanOneAndMaxOnePointFive) {
  double s = 0;
  const int n = 100000;
  for (int i = 0; i < n; ++i) s += poiseuilleProfile((i + 0.5) / n * 20e-6, 20e-6);
  EXPECT_NEAR(s / n, 1.0, 1e-9);  // midpoint rule on a parabola: error ~1/n^2
  EXPECT_NEAR(poiseuilleProfile(10e-6, 20e-6), 1.5, 1e-12);
  EXPECT_EQ(poiseuilleProfile(-1e-9, 20e-6), 0.0);
}

TEST(FlowField, HeleShawChannelVelocityWallsAndDistance) {
  HeleShawChannel ch(1e-3, 200e-6, 20e-6, 7e-4);
  EXPECT_NEAR(ch.velocityAt({1e-4, 1e-4, 5e-6}).x(), 6 * 7e-4 * 5e-6 * 15e-6 / (20e-6 * 20e-6), 1e-15);
  EXPECT_TRUE(ch.isSolid(1e-4, -1e-9));
  EXPECT_TRUE(ch.isSolid(1e-4, 201e-6));
  EXPECT_NEAR(ch.wallDistance(1e-4, 30e-6), 30e-6, 1e-18);
  EXPECT_NEAR(ch.wallDistance(1e-4, 190e-6), 10e-6, 1e-18);
  EXPECT_NEAR(ch.wallNormal(1e-4, 190e-6).y(), -1.0, 1e-12);
  EXPECT_EQ(ch.velocityAt({1e-4, -1e-6, 5e-6}).norm(), 0.0);
}

TEST(FlowField, GriddedFlowInterpolatesLinearFieldsExactlyAndBumpsVersion) {
  const int nx = 11, ny = 6;
  GriddedFlow g(nx, ny, 0.0, 0.0, 1e-5, 2e-5);
  EXPECT_EQ(g.version(), 0u);
  std::vector<double> ux(nx * ny), uy(nx * ny), h(nx * ny, 20e-6);
  std::vector<std::uint8_t> solid(nx * ny, 0);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      ux[j * nx + i] = 1e-3 + 2.0 * i * 1e-5 + 3.0 * j * 2e-5;
      uy[j * nx + i] = -1.0 * i * 1e-5;
    }
  g.update(ux, uy, h, solid);
  EXPECT_EQ(g.version(), 1u);
  const double x = 3.3e-5, y = 7.1e-5;
  EXPECT_NEAR(g.meanVelocity(x, y).x(), 1e-3 + 2 * x + 3 * y, 1e-15);
  EXPECT_NEAR(g.meanVelocity(x, y).y(), -x, 1e-15);
  EXPECT_NEAR(g.depth(x, y), 20e-6, 1e-18);
  EXPECT_THROW(g.update(ux, uy, h, std::vector<std::uint8_t>(3)), std::invalid_argument);
}

TEST(FlowField, GriddedFlowWallDistanceOfAChannelMask) {
  // Solid rows j = 0 and j = 10: walls half way to the first fluid rows, at y = 0.5 dy and 9.5 dy.
  const int nx = 8, ny = 11;
  const double dy = 1e-6;
  GriddedFlow g(nx, ny, 0.0, 0.0, dy, dy);
  std::vector<double> z(nx * ny, 0.0), h(nx * ny, 20e-6);
  std::vector<std::uint8_t> solid(nx * ny, 0);
  for (int i = 0; i < nx; ++i) solid[i] = solid[10 * nx + i] = 1;
  g.update(z, z, h, solid);
  EXPECT_NEAR(g.wallDistance(4e-6, 3e-6), 2.5e-6, 1e-12);
  EXPECT_NEAR(g.wallDistance(4e-6, 5e-6), 4.5e-6, 1e-12);
  EXPECT_NEAR(g.wallNormal(4e-6, 3.2e-6).y(), 1.0, 1e-6);
  EXPECT_TRUE(g.isSolid(4e-6, 0.2e-6));
  EXPECT_FALSE(g.isSolid(4e-6, 0.7e-6));
}

TEST(FlowField, GriddedFlowWallDistanceIsTheExactDistanceToTheSolidCells) {
  // A random mask (30 % solid nodes, each owning its dx x dy cell): within the exact reach the
  // wall distance and normal are those to the nearest solid rectangle, found here by brute
  // force over every solid cell. Tolerance: round-off of a closed-form distance (1e-9 of a cell).
  const int nx = 40, ny = 30;
  const double dx = 10e-6, dy = 10e-6;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  std::vector<std::uint8_t> solid(nx * ny);
  for (auto& s : solid) s = uni(rng) < 0.3 ? 1 : 0;
  std::vector<double> z(nx * ny, 0.0), h(nx * ny, 20e-6);
  for (const GridWalls walls : {GridWalls::cells, GridWalls::brinkman}) {
    GriddedFlow g(nx, ny, 0.0, 0.0, dx, dy, walls, 10e-6);
    g.update(z, z, h, solid);
    int checked = 0;
    for (int trial = 0; trial < 4000; ++trial) {
      const double x = uni(rng) * (nx - 1) * dx, y = uni(rng) * (ny - 1) * dy;
      if (g.isSolid(x, y)) continue;
      double best = 1e300;
      for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i) {
          if (!solid[j * nx + i]) continue;
          const double px = std::clamp(x, (i - 0.5) * dx, (i + 0.5) * dx), py = std::clamp(y, (j - 0.5) * dy, (j + 0.5) * dy);
          best = std::min(best, std::hypot(x - px, y - py));
        }
      if (best > GriddedFlow::kExactCells * dx) continue;  // beyond the exact reach: the transform's bound
      ++checked;
      ASSERT_NEAR(g.wallDistance(x, y), best, 1e-9 * dx) << "x " << x << ", y " << y;
      if (best > 1e-3 * dx) {
        // The normal points from a nearest wall point: stepping back by the distance lands on a wall
        // (on q itself unless two cells tie).
        const Vec2 n = g.wallNormal(x, y);
        EXPECT_NEAR(n.norm(), 1.0, 1e-12);
        EXPECT_NEAR(g.wallDistance(x - best * n.x(), y - best * n.y()), 0.0, 1e-9 * dx) << "x " << x << ", y " << y;
      }
    }
    EXPECT_GT(checked, 1500);  // most points of a 30 % solid mask lie within 3 cells of a wall
  }
}

TEST(FlowField, GriddedFlowBrinkmanSlotIsTheAnalyticSlotProfile) {
  // A slot two cells wide (solid rows j = 0 and 3, walls at y = 5 and 25 um) carrying the face
  // velocity U along it, 20 um deep: the match distance (resolved 10 um + half a cell = 15 um)
  // lies beyond the half-width D = 10 um, so the layer takes the slot's medial axis from the wall
  // search (bisection to 1e-3 of a cell). Each fluid row's face value is the mean over its row,
  // and the half-slot is one row, so the velocity must be the Brinkman-Hele-Shaw slot flow of
  // mean U: u(d) = U (1 - cosh((D - d) / delta) / cosh(D / delta)) / (1 - (delta / D) tanh(D / delta)),
  // delta = h / sqrt(12) (written here with cosh and tanh, the field uses exponentials).
  // Tolerance: the change of that value between D and D -+ 1e-3 cell (the bisection's
  // resolution), plus round-off; no flow across the walls (u_y zero to round-off).
  const int nx = 12, ny = 4;
  const double dx = 10e-6, depth = 20e-6, U = 1e-3, delta = depth / std::sqrt(12.0);
  GriddedFlow g(nx, ny, 0.0, 0.0, dx, dx, GridWalls::brinkman, 10e-6);
  std::vector<double> ux(nx * ny, U), uy(nx * ny, 0.0), h(nx * ny, depth);
  std::vector<std::uint8_t> solid(nx * ny, 0);
  for (int i = 0; i < nx; ++i) solid[i] = solid[(ny - 1) * nx + i] = 1;
  g.update(ux, uy, h, solid);
  ASSERT_NEAR(g.matchDistance(depth), 15e-6, 1e-18);
  const auto slot = [&](double d, double D) {
    return U * (1 - std::cosh((D - d) / delta) / std::cosh(D / delta)) / (1 - delta / D * std::tanh(D / delta));
  };
  const double D = 10e-6, wall_low = 0.5 * dx, wall_high = 2.5 * dx;
  for (const double d : {0.5e-6, 1e-6, 2.5e-6, 5e-6, 7.5e-6, 9.5e-6}) {
    const double tol = std::max(std::abs(slot(d, D - 1e-3 * dx) - slot(d, D)), std::abs(slot(d, D + 1e-3 * dx) - slot(d, D))) + 1e-12 * U;
    for (const double y : {wall_low + d, wall_high - d}) {
      const Vec2 u = g.meanVelocity(6.3 * dx, y);
      EXPECT_NEAR(u.x(), slot(d, D), tol) << "d " << d * 1e6 << " um, y " << y * 1e6 << " um";
      EXPECT_LE(std::abs(u.y()), 1e-12 * U) << "d " << d * 1e6 << " um";
    }
  }
}

}  // namespace
}  // namespace mmval::particles
