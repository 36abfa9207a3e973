// GriddedFlow remembers the nearest wall point of the last points asked (FlowField.hpp,
// nearestWallPoint), so that an engine asking the wall distance, the normal and the velocity of
// one particle's position searches the wall cells once. The contract: the answers are the
// search's, whatever was asked before, of which field and in which thread; an update forgets them.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <random>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "mmval/particles/FlowField.hpp"

namespace mmval::particles {
namespace {

constexpr double kCell = 10e-6, kDepth = 20e-6;

/// A field whose node rows j < rows are solid (the wall at y = (rows - 0.5) cells), uniform
/// flow U along x elsewhere.
void fillChannel(GriddedFlow& g, int nx, int ny, int rows, double U) {
  const auto n = static_cast<std::size_t>(nx) * ny;
  std::vector<double> ux(n, U), uy(n, 0.0), h(n, kDepth);
  std::vector<std::uint8_t> solid(n, 0);
  for (int j = 0; j < rows; ++j)
    for (int i = 0; i < nx; ++i) solid[static_cast<std::size_t>(j) * nx + i] = 1;
  g.update(ux, uy, h, solid);
}

TEST(GriddedFlowMemo, AnUpdateForgetsTheRememberedWalls) {
  // Same point, asked before and after the wall moved up by one cell: the distance is the
  // closed form to the new wall (y - (rows - 0.5) cells), to round-off (1e-9 of a cell).
  for (const GridWalls walls : {GridWalls::cells, GridWalls::brinkman}) {
    GriddedFlow g(8, 8, 0.0, 0.0, kCell, kCell, walls, kCell);
    const double x = 3.3 * kCell, y = 2.7 * kCell;
    fillChannel(g, 8, 8, 1, 1e-3);
    EXPECT_NEAR(g.wallDistance(x, y), y - 0.5 * kCell, 1e-9 * kCell);
    EXPECT_NEAR(g.wallNormal(x, y).y(), 1.0, 1e-12);
    fillChannel(g, 8, 8, 2, 1e-3);
    EXPECT_NEAR(g.wallDistance(x, y), y - 1.5 * kCell, 1e-9 * kCell);
    EXPECT_NEAR(g.wallDistance(x, y), y - 1.5 * kCell, 1e-9 * kCell);  // asked again: remembered
  }
}

TEST(GriddedFlowMemo, TwoFieldsAtOnePointKeepTheirOwnWalls) {
  // Two fields with walls one and two cells up, asked in turn at one point, and a copy made
  // before the second field's wall moved: each answers for its own walls (closed form, 1e-9 cell).
  GriddedFlow a(8, 8, 0.0, 0.0, kCell, kCell, GridWalls::brinkman, kCell), b = a;
  fillChannel(a, 8, 8, 1, 1e-3);
  fillChannel(b, 8, 8, 2, 1e-3);
  const GriddedFlow b_before = b;
  fillChannel(b, 8, 8, 3, 1e-3);
  const double x = 4.1 * kCell, y = 3.9 * kCell;
  for (int round = 0; round < 3; ++round) {
    EXPECT_NEAR(a.wallDistance(x, y), y - 0.5 * kCell, 1e-9 * kCell);
    EXPECT_NEAR(b_before.wallDistance(x, y), y - 1.5 * kCell, 1e-9 * kCell);
    EXPECT_NEAR(b.wallDistance(x, y), y - 2.5 * kCell, 1e-9 * kCell);
  }
}

/// Brute force: the distance from (x, y) to the nearest solid cell of the mask.
double bruteDistance(const std::vector<std::uint8_t>& solid, int nx, int ny, double x, double y) {
  double best = 1e300;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      if (!solid[static_cast<std::size_t>(j) * nx + i]) continue;
      const double px = std::clamp(x, (i - 0.5) * kCell, (i + 0.5) * kCell), py = std::clamp(y, (j - 0.5) * kCell, (j + 0.5) * kCell);
      best = std::min(best, std::hypot(x - px, y - py));
    }
  return best;
}

TEST(GriddedFlowMemo, InterleavedQueriesInTwoThreadsGetTheSearchsAnswers) {
  // A random mask (30 % solid); two threads ask distance, normal and velocity of their own
  // random points in an order that revisits earlier points (p_k, p_{k-1}, p_{k-2}, p_k), so
  // that remembered and evicted answers mix. Every distance within the exact reach must be the
  // brute-force one (1e-9 cell), and a point's velocity the same to the bit however often it
  // is asked (the memo returns the search's own value).
  const int nx = 40, ny = 30;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  std::vector<std::uint8_t> solid(static_cast<std::size_t>(nx) * ny);
  for (auto& s : solid) s = uni(rng) < 0.3 ? 1 : 0;
  std::vector<double> ux(solid.size(), 1e-3), uy(solid.size(), 2e-4), h(solid.size(), kDepth);
  GriddedFlow g(nx, ny, 0.0, 0.0, kCell, kCell, GridWalls::brinkman, kCell);
  g.update(ux, uy, h, solid);
  struct Answer {
    double x = 0, y = 0, d = 0;
    Vec2 u0 = Vec2::Zero(), u1 = Vec2::Zero();
  };
  const auto work = [&](unsigned seed, std::vector<Answer>& out) {
    std::mt19937 r(seed);
    std::uniform_real_distribution<double> u01(0.0, 1.0);
    std::vector<Answer> pts;
    while (pts.size() < 600) {
      const double x = u01(r) * (nx - 1) * kCell, y = u01(r) * (ny - 1) * kCell;
      if (!g.isSolid(x, y)) pts.push_back({x, y});
    }
    for (auto& p : pts) p.u0 = g.meanVelocity(p.x, p.y);
    for (std::size_t k = 2; k < pts.size(); ++k)
      for (const std::size_t m : {k, k - 1, k - 2, k}) {
        auto& p = pts[m];
        p.d = g.wallDistance(p.x, p.y);
        (void)g.wallNormal(p.x, p.y);
        p.u1 = g.meanVelocity(p.x, p.y);
      }
    out = pts;
  };
  std::vector<Answer> first, second;
  std::thread t1(work, 1u, std::ref(first)), t2(work, 2u, std::ref(second));
  t1.join();
  t2.join();
  int checked = 0;
  for (const auto* set : {&first, &second})
    for (const auto& p : *set) {
      EXPECT_EQ(p.u0.x(), p.u1.x()) << "x " << p.x << ", y " << p.y;
      EXPECT_EQ(p.u0.y(), p.u1.y()) << "x " << p.x << ", y " << p.y;
      const double best = bruteDistance(solid, nx, ny, p.x, p.y);
      if (best > GriddedFlow::kExactCells * kCell) continue;
      ++checked;
      EXPECT_NEAR(p.d, best, 1e-9 * kCell) << "x " << p.x << ", y " << p.y;
    }
  EXPECT_GT(checked, 900);  // most points of a 30 % solid mask lie within 3 cells of a wall
}

}  // namespace
}  // namespace mmval::particles
