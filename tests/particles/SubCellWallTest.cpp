// Particles see the grain surface the image draws (the pixel edges), whatever the
// fluid grid: the wall distance against brute force at every cells_per_pixel, capture
// at a grain corner decided by the exact gap, a velocity that follows the walls and
// vanishes on them, and interception in a no-slip flow against its streamline.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <utility>
#include <vector>

#include "mmval/particles/FlowField.hpp"
#include "mmval/particles/MicromodelFlow.hpp"
#include "mmval/particles/OverdampedEngine.hpp"

namespace mmval::particles {
namespace {

constexpr double kPixel = 10e-6;

/// 24 x 16 pixels: a 5 x 4 grain block, a staircase grain (convex and concave corners
/// along a 45 degree edge) and a one-pixel grain, all in open pore space.
PixelMask cornerMask() {
  PixelMask m = PixelMask::Constant(16, 24, false);
  m.block(5, 6, 4, 5) = true;                // rows 5-8, columns 6-10
  for (int k = 0; k < 5; ++k) m.block(9 + k, 15 + k, 1, 5 - k) = true;  // staircase
  m(3, 19) = true;
  return m;
}

/// Exact distance from (x, y) to the union of the solid pixels of `m` and the two side
/// walls (y < 0 and y > height: the chip's walls beyond the first and last rows).
double bruteDistance(const PixelMask& m, double x, double y) {
  const int rows = static_cast<int>(m.rows()), cols = static_cast<int>(m.cols());
  double best = std::min(y, rows * kPixel - y);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      if (!m(r, c)) continue;
      const double x0 = c * kPixel, y0 = (rows - 1 - r) * kPixel;  // row 0 at the top
      const double dx = std::max({x0 - x, 0.0, x - x0 - kPixel}), dy = std::max({y0 - y, 0.0, y - y0 - kPixel});
      best = std::min(best, std::hypot(dx, dy));
    }
  return best;
}

MicromodelFlow solved(const PixelMask& m, double cells_per_pixel, double darcy_velocity) {
  MicromodelFlowOptions o;
  o.pixel = kPixel;
  o.cells_per_pixel = cells_per_pixel;
  o.darcy_velocity = darcy_velocity;
  MicromodelFlow f(m, o);
  f.solve(PixelMask());
  return f;
}

// Round-off class: the distance to a rectangle is closed-form.
constexpr double kDistanceTolerance = 1e-9 * kPixel;

TEST(SubCellWall, WallDistanceIsExactAtEveryCellsPerPixel) {
  const PixelMask m = cornerMask();
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> ux(0.0, 24 * kPixel), uy(0.0, 16 * kPixel);
  for (const double cpp : {0.5, 1.0, 2.0}) {
    const MicromodelFlow f = solved(m, cpp, 0.0);
    const auto& g = *f.field();
    double worst = 0;
    int near_walls = 0;
    for (int k = 0; k < 4000; ++k) {
      const double x = ux(rng), y = uy(rng);
      if (g.isSolid(x, y)) continue;
      const double ref = bruteDistance(m, x, y);
      if (ref > 2 * kPixel) continue;  // the particles' business is the first ~2 radii
      ++near_walls;
      worst = std::max(worst, std::abs(g.wallDistance(x, y) - ref));
    }
    EXPECT_GT(near_walls, 1000);
    EXPECT_LE(worst, kDistanceTolerance) << "cells_per_pixel " << cpp << ": worst error " << worst / kPixel << " px";
  }
}

SceneConfig stillScene() {
  SceneConfig c;
  c.brownian = false;
  c.gravity = 0;
  c.attachment.hamaker = 0;
  c.attachment.bottom = false;
  c.attachment.capture_distance = 0.1e-6;
  return c;
}

TEST(SubCellWall, CaptureAtAGrainCornerFollowsTheExactGap) {
  // Diagonally off the block's lower right corner (x = 11 px, y = 7 px from the bottom),
  // in still fluid: a particle whose gap is below the capture distance attaches, one just
  // beyond it does not, at every fluid grid.
  const PixelMask m = cornerMask();
  const double a = 2.5e-6, cx = 11 * kPixel, cy = 7 * kPixel;
  for (const double cpp : {0.5, 1.0, 2.0}) {
    auto flow = std::make_shared<MicromodelFlow>(solved(m, cpp, 0.0));
    for (const double gap : {0.05e-6, 0.3e-6}) {
      const double r = (a + gap) / std::sqrt(2.0);
      ASSERT_NEAR(flow->field()->wallDistance(cx + r, cy - r), a + gap, kDistanceTolerance);
      OverdampedEngine e(flow->field(), stillScene());
      e.insert({Vec3(cx + r, cy - r, 10e-6)});
      e.advance(1e-3);
      EXPECT_EQ(e.counts().deposited, gap < 0.1e-6 ? 1 : 0) << "cells_per_pixel " << cpp << ", gap " << gap * 1e6 << " um";
    }
  }
}

TEST(SubCellWall, VelocityFollowsTheWallsAndVanishesOnThem) {
  // A straight channel rows 3-12 open (walls at y = 3 px and 13 px from the bottom; at
  // 0.5 cells per pixel they lie mid-cell) with the block's staircase cousin: near every wall
  // the velocity goes to zero linearly in the distance, and never points into a wall.
  PixelMask m = PixelMask::Constant(16, 24, false);
  m.topRows(3) = true;
  m.bottomRows(3) = true;
  m.block(7, 10, 2, 3) = true;  // a small grain in the channel
  for (const double cpp : {0.5, 1.0, 2.0}) {
    const MicromodelFlow f = solved(m, cpp, 1e-3);
    const auto& g = *f.field();
    const double centre = g.meanVelocity(5 * kPixel, 8 * kPixel).norm();
    ASSERT_GT(centre, 1e-4);
    for (const double d : {1e-3, 1e-2, 0.1}) {
      // Below the top wall of the lower side wall (y = 3 px) and beside the grain's faces.
      const Vec2 bottom = g.meanVelocity(5.3 * kPixel, (3 + d) * kPixel);
      EXPECT_LE(bottom.norm(), 1.5 * d / 0.5 * centre) << "cpp " << cpp << ", d " << d << " px";
      EXPECT_LE(std::abs(bottom.y()), 2 * d * centre) << "cpp " << cpp;
      const Vec2 left = g.meanVelocity((10 - d) * kPixel, 8.5 * kPixel);  // the grain's upstream face at x = 10 px
      EXPECT_LE(left.x(), 2 * d * centre) << "cpp " << cpp;  // the normal part goes to zero at least linearly
      EXPECT_LE(left.norm(), 1.5 * d / 0.5 * centre) << "cpp " << cpp << ", d " << d << " px";
    }
    // At the wall itself: nothing.
    EXPECT_LE(g.meanVelocity(5.3 * kPixel, 3 * kPixel * (1 + 1e-12)).norm(), 1e-9 * centre);
  }
}

/// Face velocities of the no-slip plane stagnation flow psi = k x y^2 on a wall y = 0
/// (u = 2 k x y, v = -k y^2: Stokes flow's leading terms at a no-slip wall) from the stream
/// function's differences, so that every cell's fluxes balance exactly. Nodes dx apart,
/// row 0 solid (its cell ends at the wall).
std::shared_ptr<GriddedFlow> stagnationFlow(double dx, double k, double length, double height) {
  const int nx = static_cast<int>(std::lround(length / dx)) + 1, ny = static_cast<int>(std::lround(height / dx)) + 2;
  auto g = std::make_shared<GriddedFlow>(nx, ny, 0.0, -0.5 * dx, dx, dx, GridWalls::cells);
  const auto n = static_cast<std::size_t>(nx) * ny;
  std::vector<double> u(n, 0.0), v(n, 0.0), h(n, 20e-6);
  std::vector<std::uint8_t> s(n, 0);
  const auto psi = [&](double x, double y) { return k * x * y * y; };
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const auto kk = static_cast<std::size_t>(j) * nx + i;
      if (j == 0) {
        s[kk] = 1;
        continue;
      }
      const double xr = (i + 0.5) * dx, yt = j * dx, yb = (j - 1) * dx, xl = (i - 0.5) * dx;
      u[kk] = (psi(xr, yt) - psi(xr, yb)) / dx;   // right face: flux / length
      v[kk] = -(psi(xr, yt) - psi(xl, yt)) / dx;  // top face
    }
  g->update(u, v, h, s);
  return g;
}

TEST(SubCellWall, InterceptionInANoSlipFlowFollowsTheStreamline) {
  // A particle centre carried along psi = x y^2 = const from (x0, y0) comes within a + cd of
  // the wall at x = x0 y0^2 / (a + cd)^2: it is intercepted before the outlet x = L when
  // y0 < (a + cd) sqrt(L / x0) (the interception result for a point centre on a streamline).
  // The critical starting height, by bisection, converges to it with the grid spacing.
  const double a = 2.5e-6, cd = 0.1e-6, x0 = 20e-6, L = 320e-6, k = 2e5;
  const double expect = (a + cd) * std::sqrt(L / x0);  // 10.4 um
  SceneConfig c = stillScene();
  c.depth_profile = false;  // plane flow: the particle moves with the field
  c.wall_hindrance = false;
  c.max_step_fraction = 0.05;
  // Tolerance: the face interpolation is exact for u (linear in y) and, in the wall's own
  // cell, for v; in the cells above, v = -k y^2 is taken linearly between faces, which
  // overstates |v| by up to (dx / 2 y)^2 (the chord of a parabola) and so lets particles from
  // up to ~20 % higher reach the wall at dx = 5-10 um (measured 15 %, 19 %; the node field
  // before gave -18 %, +23 %). The error falls as dx^2: at 2.5 um it is 1.5 % (nodes: 7 %).
  for (const double dx : {10e-6, 5e-6, 2.5e-6}) {
    const auto flow = stagnationFlow(dx, k, L, 40e-6);
    const auto intercepted = [&](double y0) {
      OverdampedEngine e(flow, c);
      e.insert({Vec3(x0, y0, 10e-6)});
      for (int chunk = 0; chunk < 200 && e.counts().deposited + e.counts().left == 0; ++chunk) e.advance(e.time() + 0.05);
      return e.counts().deposited == 1;
    };
    double lo = 1.05 * (a + cd), hi = 3 * expect;
    ASSERT_TRUE(intercepted(lo));
    ASSERT_FALSE(intercepted(hi));
    for (int it = 0; it < 14; ++it) {
      const double mid = 0.5 * (lo + hi);
      (intercepted(mid) ? lo : hi) = mid;
    }
    const double found = 0.5 * (lo + hi);
    EXPECT_NEAR(found, expect, (dx > 3e-6 ? 0.22 : 0.03) * expect) << "dx = " << dx * 1e6 << " um";
  }
}

TEST(SubCellWall, BrinkmanLayerAtAStraightWallConvergesToTheAnalyticProfile) {
  // A straight channel 120 um wide (rows 2-13 open) in a 20 um deep chip: the depth-averaged
  // Brinkman-Hele-Shaw flow is u(y) = U0 (1 - cosh((y - w/2) / delta) / cosh(w / (2 delta))),
  // delta = h / sqrt(12), its mean (the Darcy velocity times H / w, the flux the solve is scaled
  // to) U0 (1 - (2 delta / w) tanh(w / (2 delta))). The velocity particles feel at 2.5, 5 and
  // 10 um from either wall must follow it, converging with the fluid cell (20, 10, 5, 2.5 um).
  // The layer's amplitude is the solve's flux between the wall and half a spacing beyond the
  // match distance (psi's value there, over the profile's integral G), so it carries the solve's error
  // in the flux beside the wall, where delta (5.8 um) is not resolved on the coarse grids:
  // measured +6.6 / +7.1 / +2.4 / +0.7 % at 0.5 / 1 / 2 / 4 cells per pixel. Bounds: 8 % on the
  // two coarse grids, 3 % and 1 % on the fine ones, and the error falls from 1 to 2 to 4 cells per
  // pixel. (The slope of psi over the strip around the match distance gave -4.6 / -1.3 / -0.45 %
  // on the first three, but the flux it left out of the layer re-entered in the blend band beyond
  // it: a ribbon whose velocity changed by over 5 % of the mean flow within 10 nm at 10-18 % of
  // the band's points on the paper's strip, 2-3 % with the value; LayerSpikeTest.) The profile's
  // shape is exact by construction: the ratio of two distances within 1e-6 (round-off and the far
  // wall's e^-20 tail). No flow into the walls: the transverse velocity is the solve's round-off
  // (measured below 2e-14 U0; 1.5e-6 U0 while the outlet's face nodes read fluid beyond the image
  // and let flow out through the walls, see MicromodelFlow's solverShape). The linear no-slip
  // expansion (GridWalls::cells) gives 0.95-1.49 of the analytic value on the same grids.
  constexpr double kShape = 1e-6;
  const int rows = 16, cols = 24, wall = 2;
  PixelMask m = PixelMask::Constant(rows, cols, false);
  m.topRows(wall) = true;
  m.bottomRows(wall) = true;
  const double depth = 20e-6, delta = depth / std::sqrt(12.0), w = (rows - 2 * wall) * kPixel, darcy = 1e-3;
  const double U0 = darcy * rows * kPixel / w / (1 - 2 * delta / w * std::tanh(w / (2 * delta)));
  const auto exact = [&](double d) { return U0 * (1 - std::cosh((d - w / 2) / delta) / std::cosh(w / (2 * delta))); };
  const std::vector<std::pair<double, double>> grids = {{0.5, 0.08}, {1.0, 0.08}, {2.0, 0.03}, {4.0, 0.01}};
  std::vector<double> worst;
  for (const auto& [cpp, bound] : grids) {
    const MicromodelFlow f = solved(m, cpp, darcy);
    const auto& g = *f.field();
    const double x = 12.3 * kPixel, y_low = wall * kPixel, y_high = (rows - wall) * kPixel;
    double err = 0;
    for (const double d : {2.5e-6, 5e-6, 10e-6}) {
      for (const double y : {y_low + d, y_high - d}) {
        const Vec2 u = g.meanVelocity(x, y);
        EXPECT_NEAR(u.x() / exact(d), 1.0, bound) << "cpp " << cpp << ", d " << d * 1e6 << " um, y " << y * 1e6 << " um";
        err = std::max(err, std::abs(u.x() / exact(d) - 1.0));
        EXPECT_LE(std::abs(u.y()), 1e-9 * U0) << "cpp " << cpp;  // no flow into a straight wall
      }
      const double ratio = g.meanVelocity(x, y_low + d).x() / g.meanVelocity(x, y_low + 10e-6).x();
      EXPECT_NEAR(ratio, exact(d) / exact(10e-6), kShape) << "cpp " << cpp << ", d " << d * 1e6 << " um";
    }
    worst.push_back(err);
  }
  EXPECT_LT(worst[2], worst[1]);
  EXPECT_LT(worst[3], worst[2]);
}

TEST(SubCellWall, DiscGrainDistanceIsToTheBoundaryTheSolverUses) {
  // The micromodel solve cuts against the pixel mask itself (simulate::MaskShape), so the
  // particles' wall is the disc's pixel outline: its distance against brute force, within
  // 0.05 px (it is exact up to round-off), all around a disc of radius 6 px.
  PixelMask m = PixelMask::Constant(20, 20, false);
  for (int r = 0; r < 20; ++r)
    for (int c = 0; c < 20; ++c) m(r, c) = std::hypot(c + 0.5 - 10.0, r + 0.5 - 10.0) <= 6.0;
  const MicromodelFlow f = solved(m, 1.0, 0.0);
  const auto& g = *f.field();
  double worst = 0;
  for (int k = 0; k < 360; ++k)
    for (const double gap_px : {0.1, 0.26, 0.5, 1.0, 2.0}) {
      const double phi = k * M_PI / 180, rr = 6.5 + gap_px;
      const double x = (10 + rr * std::cos(phi)) * kPixel, y = (10 + rr * std::sin(phi)) * kPixel;
      if (g.isSolid(x, y)) continue;
      worst = std::max(worst, std::abs(g.wallDistance(x, y) - bruteDistance(m, x, y)));
    }
  EXPECT_LE(worst, 0.05 * kPixel) << "worst " << worst / kPixel << " px";
}

}  // namespace
}  // namespace mmval::particles
