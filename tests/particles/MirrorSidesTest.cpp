// Mirror (slip) sides of the micromodel scene (geometry.sides = "slip") and of the chip generator
// (mmval chip --wall-px 0), each against an independent reference: plug flow with no wall layer in
// an empty slip strip (Hele-Shaw: u = U, k = h^2 / 12), the field's mirror symmetry across the
// plane, the throat between a grain and the plane (twice its distance, from the geometry),
// reflected Brownian motion (the method of images: |W|, so <y^2> = 2 D t and <y> = sqrt(4 D t / pi)),
// and the generator's throats and grain clearances on hand-placed discs.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "mmval/particles/MicromodelFlow.hpp"
#include "mmval/particles/OverdampedEngine.hpp"
#include "mmval/simulate/ChipPacking.hpp"

namespace mmval::particles {
namespace {

constexpr double kPixel = 10e-6, kDepth = 20e-6;

MicromodelFlow solvedStrip(const PixelMask& m, bool mirror, double darcy_velocity, double cells_per_pixel = 1.0) {
  MicromodelFlowOptions o;
  o.pixel = kPixel;
  o.depth = kDepth;
  o.cells_per_pixel = cells_per_pixel;
  o.darcy_velocity = darcy_velocity;
  o.mirror_sides = mirror;
  MicromodelFlow f(m, o);
  f.solve(PixelMask());
  return f;
}

TEST(MicromodelMirrorSides, EmptySlipStripIsPlugFlowUpToThePlanes) {
  // No grains, slip sides: the depth-averaged Stokes-Hele-Shaw solution is uniform, u = U and
  // k = h^2 / 12 (Hele-Shaw), with no Brinkman layer at the sides. With walls the particles' field
  // has the layer u = U (1 - exp(-d / delta)), delta = h / sqrt(12), at the edges.
  const PixelMask m = PixelMask::Constant(12, 40, false);
  const double U = 1e-4, H = 12 * kPixel;
  const MicromodelFlow slip = solvedStrip(m, true, U), walls = solvedStrip(m, false, U);
  const auto& f = *slip.field();
  EXPECT_DOUBLE_EQ(f.bounds().y0, 0.0);
  EXPECT_DOUBLE_EQ(f.bounds().y1, H);
  for (const double y : {1e-9, 0.1e-6, 2e-6, 0.5 * kPixel, 3 * kPixel, 0.5 * H, H - 0.1e-6, H - 1e-9}) {
    const Vec2 u = f.meanVelocity(20 * kPixel, y);
    EXPECT_NEAR(u.x(), U, 1e-9 * U) << "y = " << y * 1e6 << " um";
    EXPECT_NEAR(u.y(), 0.0, 1e-9 * U) << "y = " << y * 1e6 << " um";
    EXPECT_GT(f.wallDistance(20 * kPixel, y), 10 * kPixel) << "no wall at a mirror plane";
  }
  // The walled field at 0.1 um from the edge: the layer, 1 - exp(-0.1 / 5.77) = 1.7 % of U (the
  // match to the face velocity changes its amplitude by little).
  EXPECT_LT(walls.field()->meanVelocity(20 * kPixel, 0.1e-6).x(), 0.05 * U);
  EXPECT_NEAR(walls.field()->wallDistance(20 * kPixel, 0.1e-6), 0.1e-6, 1e-12);
}

TEST(MicromodelMirrorSides, FieldBeyondAPlaneIsTheMirrorImage) {
  // Grains near both edges: beyond each plane the particles' field is the pore space mirrored
  // (u_x the same, u_y reversed, the same wall distance), so that points within the image see the
  // mirrored grains; on the plane itself u_y = 0.
  PixelMask m = PixelMask::Constant(14, 30, false);
  m.block(12, 8, 2, 3) = true;   // touching the bottom edge
  m.block(10, 17, 2, 2) = true;  // one pixel from it
  m.block(0, 12, 1, 4) = true;   // on the top edge
  m.block(4, 22, 3, 3) = true;
  const double U = 2e-4, H = 14 * kPixel;
  const MicromodelFlow flow = solvedStrip(m, true, U, 0.5);
  const auto& f = *flow.field();
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> ux(0.0, 30 * kPixel), uy(1e-8, 3 * kPixel);
  int tested = 0, on_plane = 0, near_walls = 0;
  for (int k = 0; k < 3000; ++k) {
    const double x = ux(rng), d = uy(rng);
    for (const auto& [y_in, y_out] : {std::pair{d, -d}, std::pair{H - d, H + d}}) {
      ASSERT_EQ(f.isSolid(x, y_in), f.isSolid(x, y_out));
      if (f.isSolid(x, y_in)) continue;
      ++tested;
      const Vec2 a = f.meanVelocity(x, y_in), b = f.meanVelocity(x, y_out);
      EXPECT_NEAR(b.x(), a.x(), 1e-9 * U);
      EXPECT_NEAR(b.y(), -a.y(), 1e-9 * U);
      // Exact distances within the wall search's reach (beyond it the field reads only a lower
      // bound from its node transform, which does not reach past the padding).
      if (f.wallDistance(x, y_in) < f.matchDistance(kDepth)) {
        ++near_walls;
        EXPECT_NEAR(f.wallDistance(x, y_out), f.wallDistance(x, y_in), 1e-9 * kPixel);
      }
    }
    // On the plane itself u_y = 0 where the face velocities decide (beyond the near-wall layer;
    // within it a point on the plane is equidistant to a grain corner and its image, and the tie
    // picks one, as on any medial axis between two grains).
    if (!f.isSolid(x, 0.0) && f.wallDistance(x, 0.0) > f.matchDistance(kDepth)) {
      ++on_plane;
      EXPECT_NEAR(f.meanVelocity(x, 0.0).y(), 0.0, 1e-9 * U);
    }
  }
  EXPECT_GT(tested, 4000);
  EXPECT_GT(on_plane, 1000);
  EXPECT_GT(near_walls, 500);
}

TEST(MicromodelMirrorSides, ThroatToAPlaneIsTwiceTheDistance) {
  // A barrier across the strip leaves a gap of 3 px at the bottom edge. With walls the particles
  // pass through 3 px; with a mirror plane the gap meets its image: 6 px, read as 5 px at the pixel
  // centres (passableDiameter: an even throat of n px reads n - 1).
  PixelMask m = PixelMask::Constant(20, 30, false);
  m.block(0, 14, 17, 3) = true;  // rows 0-16: the bottom 3 rows stay open
  EXPECT_NEAR(passableDiameter(m, kPixel, false), 3 * kPixel, 1e-9 * kPixel);
  EXPECT_NEAR(passableDiameter(m, kPixel, true), 5 * kPixel, 1e-9 * kPixel);
  // The inlet column: with walls the widest disc spans the strip (20 px, read 19 at the pixel
  // centres); with mirror planes only the barrier downstream bounds it: from the bottom pixel's
  // centre (0.5, 0.5) px to the barrier's nearest pixel centre (14.5, 3.5) less half a pixel (the
  // distances are between pixel centres).
  EXPECT_NEAR(inletOpening(m, kPixel, false), 19 * kPixel, 1e-9 * kPixel);
  EXPECT_NEAR(inletOpening(m, kPixel, true), 2 * (std::hypot(14.0, 3.0) - 0.5) * kPixel, 1e-9 * kPixel);
}

TEST(MicromodelMirrorSides, BrownianParticlesAreReflectedAsByTheMethodOfImages) {
  // Still fluid, no hindrance, no attachment: particles released on the plane y = 0 diffuse as
  // reflected Brownian motion, y = |W(t)| (the method of images), so <y^2> = 2 D t and
  // <y> = sqrt(4 D t / pi), with D = k_B T / (6 pi mu a) (Stokes-Einstein). None is lost at the
  // planes: injected = inside, all within [0, H]. A plane that captured, clamped or let them leave
  // fails the counts or the mean (clamping at 0 gives <y> half the reflected value).
  const int n = 400;
  const double spacing = 40e-6, a = 2.5e-6;
  const double margin = 100e-6;  // 10 sigma from the inlet and the outlet
  const int cols = static_cast<int>(std::lround((2 * margin + n * spacing) / kPixel));
  const PixelMask m = PixelMask::Constant(10, cols, false);  // H = 100 um, 10 sigma from the release
  const MicromodelFlow flow = solvedStrip(m, true, 0.0, 0.5);
  SceneConfig c;
  c.particle.diameter = 2 * a;
  c.gravity = 0;
  c.wall_hindrance = false;
  c.brownian = true;
  c.attachment.capture_distance = 0;  // no attachment anywhere
  c.straining.enabled = false;
  c.mirror_sides = true;
  c.max_step_fraction = 0.5;
  c.seed = 3;
  OverdampedEngine e(flow.field(), c);
  std::vector<Vec3> pos;
  for (int k = 0; k < n; ++k) pos.emplace_back(margin + (k + 0.5) * spacing, 0.0, 0.5 * kDepth);
  e.insert(pos);
  const double kT = 1.380649e-23 * c.fluid.temperature, D = kT / (6 * M_PI * c.fluid.viscosity * a);
  const double sigma = 10e-6, t = sigma * sigma / (2 * D);  // ~580 s
  e.advance(t);
  const Counts k = e.counts();
  EXPECT_EQ(k.injected, n);
  EXPECT_EQ(k.inside, n);
  double m1 = 0, m2 = 0;
  for (const auto& p : e.particles()) {
    EXPECT_GE(p.x.y(), 0.0);
    EXPECT_LE(p.x.y(), 10 * kPixel);
    m1 += p.x.y() / n;
    m2 += p.x.y() * p.x.y() / n;
  }
  // Tolerances: 4 standard errors of the sample means (|W| has SD sigma sqrt(1 - 2 / pi) = 0.60
  // sigma; W^2 has SD sqrt(2) sigma^2), over 400 particles.
  const double mean = sigma * std::sqrt(2 / M_PI);
  EXPECT_NEAR(m1, mean, 4 * 0.603 * sigma / std::sqrt(n)) << "<y> / sigma = " << m1 / sigma;
  EXPECT_NEAR(m2, sigma * sigma, 4 * std::sqrt(2.0) * sigma * sigma / std::sqrt(n)) << "<y^2> / sigma^2 = " << m2 / (sigma * sigma);
}

TEST(ChipMirrorSides, ThroatToTheOwnImageIsTwiceTheDistanceToTheEdge) {
  // One disc of radius 5 px, its surface 3 px below the top edge of a 40-row pattern. Walls of
  // 2 px: the throat to the wall is 8 - 2 - 5 = 1 px. Mirror sides (wall_px 0): the throat to its
  // own image is 2 x 3 = 6 px, its midpoint on the edge; the bottom edge is 27 px away (54 px: beyond
  // the largest width asked).
  const std::vector<simulate::ChipDisc> one{{50, 8, 5}};
  const auto walls = simulate::chipThroats(one, 40, 2, 20);
  ASSERT_EQ(walls.size(), 1u);
  EXPECT_NEAR(walls[0].width_px, 1.0, 1e-12);
  const auto mirror = simulate::chipThroats(one, 40, 0, 20);
  ASSERT_EQ(mirror.size(), 1u);
  EXPECT_NEAR(mirror[0].width_px, 6.0, 1e-12);
  EXPECT_NEAR(mirror[0].y, 0.0, 1e-12);
  // Two discs near the bottom edge (y = 40): A (20, 34, r 4) 2 px from it, B (31, 35, r 4) 1 px.
  // Throats: each to its own image (4 and 2 px, midpoints on the edge) and A-B (hypot(11, 1) - 8).
  // A with B's image (31, 45) has its midpoint (25.5, 39.5) inside but only 3.1 px from B, nearer
  // than its half-width 3.78: no throat; B with A's image has its midpoint outside.
  const std::vector<simulate::ChipDisc> two{{20, 34, 4}, {31, 35, 4}};
  const auto t2 = simulate::chipThroats(two, 40, 0, 12);
  ASSERT_EQ(t2.size(), 3u);
  std::vector<double> w;
  for (const auto& t : t2) w.push_back(t.width_px);
  std::sort(w.begin(), w.end());
  EXPECT_NEAR(w[0], 2.0, 1e-12);
  EXPECT_NEAR(w[1], std::hypot(11.0, 1.0) - 8, 1e-12);
  EXPECT_NEAR(w[2], 4.0, 1e-12);
}

TEST(ChipMirrorSides, PackedGrainsKeepHalfTheGapFromTheEdgesAndNoWallRows) {
  simulate::ChipPackingSpec s;
  s.cols = 240;
  s.rows = 60;
  s.wall_px = 0;
  s.port_px = 10;
  s.mean_diameter_px = 12;
  s.min_gap_px = 3;
  s.porosity = 0.6;
  s.seed = 4;
  const simulate::ChipPacking p = simulate::packChip(s);
  for (const auto& d : p.discs) {
    EXPECT_GE(d.y - d.r, 0.5 * s.min_gap_px - 1e-6);
    EXPECT_GE(s.rows - d.y - d.r, 0.5 * s.min_gap_px - 1e-6);
  }
  // No solid rows: the edges' pixel rows are mostly pore (grains only touch within half a gap).
  EXPECT_LT(p.solid.row(0).count(), s.cols / 2);
  EXPECT_LT(p.solid.row(s.rows - 1).count(), s.cols / 2);
  EXPECT_NEAR(p.porosity_total, s.porosity, s.porosity_tolerance);
  // Every throat to a grain's own image (midpoint on an edge) is at least the minimum gap; the
  // others too, to the relaxation's tolerance (0.1 px, ChipPacking.cpp kOverlapDonePx).
  int to_edge = 0;
  for (const auto& t : simulate::chipThroats(p.discs, s.rows, 0, s.mean_diameter_px)) {
    const bool on_edge = std::abs(t.y) < 1e-9 || std::abs(t.y - s.rows) < 1e-9;
    to_edge += on_edge ? 1 : 0;
    EXPECT_GE(t.width_px, s.min_gap_px - (on_edge ? 1e-9 : 0.1));
  }
  EXPECT_GT(to_edge, 5);
}

}  // namespace
}  // namespace mmval::particles
