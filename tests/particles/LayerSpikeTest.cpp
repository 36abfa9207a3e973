// The near-wall layer on a real chip image: no point of it moves faster than the flow around it.
//
// The layer's velocity is the curl of a stream function built per point from that point's
// nearest wall, slot width and amplitude (FlowFieldLayer.cpp). Where two nearby points take
// different walls (two grains' walls that do not face each other, a wall and a corner), the
// stream function can jump between them, and a difference across the jump is a velocity of
// (jump / step), three orders of magnitude above the flow. On the paper's 20 mm strip this
// happened every second engine step (the engine's step is the smallest over all particles), so
// every particle moved in steps ~100x shorter than its own flow asked for.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "mmval/particles/FlowField.hpp"
#include "mmval/particles/MicromodelFlow.hpp"
#include "mmval/simulate/Geometry.hpp"

namespace mmval::particles {
namespace {

/// The largest node speed of the solved field (the bulk's fastest flow anywhere in the crop).
double fastestBulk(const MicromodelFlow& f) {
  double best = 0;
  for (std::size_t k = 0; k < f.nodeUx().size(); ++k) best = std::max(best, std::hypot(f.nodeUx()[k], f.nodeUy()[k]));
  return best;
}

/// The strip's mask, its crop of `cols` columns from `c0`, and that crop's flow solved at the
/// case's 0.5 cells per pixel (2 um per pixel, 20 um deep, 5 uL/min over 10 mm: Darcy velocity
/// 4.17e-4 m/s).
constexpr double kPixel = 2e-6;
std::unique_ptr<MicromodelFlow> solvedCrop(int c0, int cols, bool smooth) {
  static const auto full = simulate::readMask(std::string(MMVAL_SOURCE_DIR) + "/cases/data/paper-chip-strip.png", true);
  MicromodelFlowOptions o;
  o.pixel = kPixel;
  o.depth = 20e-6;
  o.cells_per_pixel = 0.5;
  o.darcy_velocity = 4.17e-4;
  o.smooth_walls = smooth;
  auto f = std::make_unique<MicromodelFlow>(PixelMask(full.block(0, c0, full.rows(), cols)), o);
  if (f->solve({}).blocked) return nullptr;
  return f;
}

// Crops of the paper's strip (cases/data/paper-chip-strip.png, 2 um per pixel, 20 um deep; the
// strip's own flow rate, 5 uL/min over 10 mm: Darcy velocity 4.17e-4 m/s), both wall kinds, the
// case's 0.5 cells per pixel. 40,000 random points in the pore space of each crop: the layer's speed
// against the fastest node velocity of the crop (the bulk's fastest flow). A Brinkman layer beside a
// wall is slower than the flow beyond it (its profile g(d) <= 1 in a slot and on an open wall); the
// bound, 8x, leaves room for what the layer does that is not yet right but is not a jump: the
// blend into the bilinear psi over the outer half spacing (d 6.0-6.6 um of d_m 7.8) reaches 2-3x
// (4-23 points of 40,000 over 2x). Measured with the central difference across jumps: 74-114x,
// 14-24 points of 40,000 over 8x (the test fails); with the jump test: 2.3-3.2x, none over 8x.
constexpr double kBound = 8;

TEST(LayerSpike, NoPointOfTheNearWallLayerOutrunsTheFlowOnTheStrip) {
  const int cols = 400;
  for (const int c0 : {1000, 5200})
    for (const bool smooth : {false, true}) {
      SCOPED_TRACE(::testing::Message() << "columns " << c0 << "+" << cols << ", " << (smooth ? "smooth" : "pixels"));
      const auto f = solvedCrop(c0, cols, smooth);
      ASSERT_TRUE(f);
      const GriddedFlow& g = *f->field();
      const double X = cols * kPixel, Y = static_cast<double>(f->grains().rows()) * kPixel;
      const double bulk = fastestBulk(*f);
      std::mt19937_64 rng(7);
      std::uniform_real_distribution<double> ux(0, X), uy(0, Y);
      int n = 0, over = 0;
      double worst = 0;
      Vec2 worst_at(0, 0);
      while (n < 40000) {
        const double x = ux(rng), y = uy(rng);
        if (g.isSolid(x, y)) continue;
        ++n;
        const double s = g.meanVelocity(x, y).norm();
        over += s > kBound * bulk;
        if (s > worst) {
          worst = s;
          worst_at = Vec2(x, y);
        }
      }
      std::printf("%s columns %d: fastest node %.3g m/s, fastest layer point %.3g m/s (%.3g x) at %.2f, %.2f px; %d of %d over the bound\n",
                  smooth ? "smooth" : "pixels", c0, bulk, worst, worst / bulk, worst_at.x() / kPixel, worst_at.y() / kPixel, over, n);
      EXPECT_EQ(over, 0);
    }
}

// No slip on the smooth walls: within 10 nm of the contour the layer moves at ~d / delta of the
// flow beyond it (~2e-3 here). 200,000 random pore points within 10 um of the wall per crop (as
// they fall: ~250 of them within 10 nm); bound for those: a tenth of the fastest node speed. Before
// the thin-slot taper a point where q's ray met another part of the contour at once (a concave
// kink) made a slot of half-width ~d, and B g(d) ~ 2 (psi - psi_w) / d: up to 17x (columns 1000)
// and 8.7x (5200) the fastest node speed (the test fails); after it, 0.005-0.006.
TEST(LayerSpike, TheLayerIsAtRestOnTheSmoothWall) {
  const int cols = 400;
  for (const int c0 : {1000, 5200}) {
    SCOPED_TRACE(::testing::Message() << "columns " << c0 << "+" << cols);
    const auto f = solvedCrop(c0, cols, true);
    ASSERT_TRUE(f);
    const GriddedFlow& g = *f->field();
    const double bulk = fastestBulk(*f), X = cols * kPixel, Y = static_cast<double>(f->grains().rows()) * kPixel;
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> ux(0, X), uy(0, Y);
    int at_wall = 0;
    double worst = 0;
    for (int n = 0; n < 200000;) {
      const double x = ux(rng), y = uy(rng);
      if (g.isSolid(x, y)) continue;
      const double d = g.wallDistance(x, y);
      if (d > 10e-6) continue;
      ++n;
      if (d > 10e-9) continue;
      ++at_wall;
      worst = std::max(worst, g.meanVelocity(x, y).norm());
    }
    std::printf("columns %d: %d points within 10 nm of the smooth wall, fastest %.3g of the fastest node\n", c0, at_wall, worst / bulk);
    EXPECT_GE(at_wall, 100);
    EXPECT_LT(worst, 0.1 * bulk);
  }
}

}  // namespace
}  // namespace mmval::particles
