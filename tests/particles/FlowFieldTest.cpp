// Flow fields: exact answers for analytic fields, interpolation exact for linear data.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include <cstdio>

#include "mmval/particles/FlowField.hpp"
#include "mmval/particles/MicromodelFlow.hpp"

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

// The Brinkman layer beside a disc grain is the curl of a stream function: no sources or sinks.
// A disc of radius 5 px (2 um pixels, 20 um deep) in a 40 x 21 px channel, MicromodelFlow
// (balanced faces) at 0.5 and 1 cells per pixel, pixel and smooth walls. Along its front (rays
// within 40 degrees of -x from the centre, 0.25 degrees apart: the pixel staircase's steps and the
// smooth contour's kinks included) at wall distance a = 2.5 um (a 5 um particle's centre) and a / 2:
// - the divergence by central differences of 0.05 um against |u|_mean / a: below 0.1 at 85 % of the
//   points or more (measured 89-99 %, largest 0.3-0.4 at a on both walls; at a / 2 up to 15 on pixel
//   walls, where a difference straddles a concave corner's bisector: the nearest wall point jumps
//   there and the velocity's tangential part with it, psi does not). The layer before this one (an
//   amplitude per point from the face velocity at q's match point, docs/validation/paper-scenes.md
//   "What holds particles at the strip's trap places") read below 0.1 at 0-8 % of them, largest 16-54;
// - the net flux out of squares of side 1 um centred on every 8th point (400 midpoints per side)
//   against the flux through one side: below 0.03 (measured 1.6e-4 smooth, 0.005-0.012 pixels: the
//   band of the curl's step, 2 x 0.004 um, along each concave corner's bisector, where the difference
//   along the wall and the derivative along q's normal are taken in different frames). The layer
//   before: 0.46-1.9.
TEST(FlowField, BrinkmanLayerBesideADiscIsTheCurlOfAStreamFunction) {
  constexpr double kPi = 3.14159265358979323846;
  const int rows = 21, cols = 40;
  const double px = 2e-6, R = 5.0, cx = 20.0, cy = 10.5, a = 2.5e-6;
  PixelMask m = PixelMask::Constant(rows, cols, false);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) m(r, c) = std::hypot(c + 0.5 - cx, rows - r - 0.5 - cy) < R;
  for (const bool smooth : {false, true})
    for (const double cpp : {0.5, 1.0}) {
      SCOPED_TRACE(::testing::Message() << (smooth ? "smooth" : "pixels") << ", " << cpp << " cells per pixel");
      MicromodelFlowOptions o;
      o.pixel = px;
      o.depth = 20e-6;
      o.cells_per_pixel = cpp;
      o.darcy_velocity = 4.2e-4;
      o.smooth_walls = smooth;
      MicromodelFlow f(m, o);
      ASSERT_FALSE(f.solve({}).blocked);
      const GriddedFlow& g = *f.field();
      for (const double dist : {a, 0.5 * a}) {
        std::vector<Vec2> pts;
        for (int k = -160; k <= 160; ++k) {
          const double phi = kPi + k * 0.25 * kPi / 180;
          const Vec2 dir(std::cos(phi), std::sin(phi)), c(cx * px, cy * px);
          double lo = 0, hi = (R + 4) * px;  // wall distance grows along the ray
          for (int it = 0; it < 60; ++it) {
            const double mid = 0.5 * (lo + hi);
            const Vec2 p = c + mid * dir;
            (g.wallDistance(p.x(), p.y()) < dist ? lo : hi) = mid;
          }
          pts.push_back(c + hi * dir);
        }
        double mean = 0;
        for (const Vec2& p : pts) mean += g.meanVelocity(p.x(), p.y()).norm() / pts.size();
        const double e = 0.05e-6;
        int small = 0;
        double worst_div = 0, worst_loop = 0;
        Vec2 worst_at(0, 0);
        for (std::size_t kp = 0; kp < pts.size(); ++kp) {
          const Vec2& p = pts[kp];
          const auto u = [&](double x, double y) { return g.meanVelocity(x, y); };
          const double div = (u(p.x() + e, p.y()).x() - u(p.x() - e, p.y()).x() + u(p.x(), p.y() + e).y() - u(p.x(), p.y() - e).y()) / (2 * e);
          const double rel = std::abs(div) / (mean / a);
          worst_div = std::max(worst_div, rel);
          small += rel < 0.1;
          if (kp % 8 != 0) continue;
          // Net flux out of a square of side s around p (depth uniform: h cancels).
          const double s = 1e-6;
          const int nq = 400;
          double net = 0, side = 0;
          for (int q = 0; q < nq; ++q) {
            const double off = (q + 0.5) / nq * s - 0.5 * s;
            net += (u(p.x() + 0.5 * s, p.y() + off).x() - u(p.x() - 0.5 * s, p.y() + off).x() + u(p.x() + off, p.y() + 0.5 * s).y() -
                    u(p.x() + off, p.y() - 0.5 * s).y()) * s / nq;
            side += std::abs(u(p.x() - 0.5 * s, p.y() + off).x()) * s / nq;
          }
          if (std::abs(net) / side > worst_loop) worst_at = p;
          worst_loop = std::max(worst_loop, std::abs(net) / side);
        }
        std::printf("%s %.1f cpp, d %.2f um: |div u| largest %.3g |u|/a, below 0.1 at %d of %zu; loop flux %.2g\n", smooth ? "smooth" : "pixels", cpp,
                    dist * 1e6, worst_div, small, pts.size(), worst_loop);
        EXPECT_GE(small, static_cast<int>(0.85 * pts.size())) << "largest " << worst_div;
        EXPECT_LT(worst_loop, 0.03) << "at " << worst_at.x() / px << ", " << worst_at.y() / px << " px";
      }
    }
}

}  // namespace
}  // namespace mmval::particles
