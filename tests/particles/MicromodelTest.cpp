// Pieces of the coupled micromodel scene (issue 6), each against an
// independent reference: the distance transform against brute force, deposit
// volume conservation, throat bottlenecks of masks with known widths, engine
// checkpoints against uninterrupted runs, and bad insertions.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "mmval/core/Error.hpp"
#include "mmval/particles/DepositGrid.hpp"
#include "mmval/particles/MicromodelFlow.hpp"
#include "mmval/particles/OverdampedEngine.hpp"

namespace mmval::particles {
namespace {

TEST(Micromodel, DistanceTransformMatchesBruteForce) {
  // Random mask: the O(N) transform must equal the exact Euclidean distance to the
  // nearest solid node (minus half a cell) to round-off.
  const int nx = 37, ny = 23;
  const double dx = 1e-6, dy = 1.5e-6;
  std::mt19937 rng(7);
  std::bernoulli_distribution solid(0.15);
  std::vector<std::uint8_t> s(nx * ny);
  for (auto& v : s) v = solid(rng) ? 1 : 0;
  std::vector<double> zero(nx * ny, 0.0), h(nx * ny, 1e-5);
  GriddedFlow g(nx, ny, 0, 0, dx, dy);
  g.update(zero, zero, h, s);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      if (s[j * nx + i]) continue;
      double best = 1e300;
      for (int b = 0; b < ny; ++b)
        for (int a = 0; a < nx; ++a)
          if (s[b * nx + a]) best = std::min(best, std::hypot((a - i) * dx, (b - j) * dy));
      const double expect = std::max(0.0, best - 0.5 * dx);
      EXPECT_NEAR(g.wallDistance(i * dx, j * dy), expect, 1e-12 * dx) << i << "," << j;
    }
}

TEST(Micromodel, DepositVolumeIsConservedAndSpillsIntoPoresOnly) {
  PixelMask grains = PixelMask::Constant(5, 5, false);
  grains(2, 3) = true;  // a grain right of the centre pixel
  const double px = 10e-6, h = 20e-6;
  DepositGrid g(grains, px, h, 0.5);
  const double cap = 0.5 * px * px * h;
  EXPECT_NEAR(g.capacity(), cap, 1e-12 * cap);
  // 3.5 capacities at the centre pixel (row 2, col 2): it closes, then its nearest
  // open neighbours (distance 1: up, left, down; the grain is skipped) take the rest.
  const int closed = g.add(2.5 * px, 2.5 * px, 3.5 * cap);
  EXPECT_EQ(closed, 3);
  EXPECT_EQ(g.closedCount(), 3);
  EXPECT_TRUE(g.closed()(2, 2));
  EXPECT_FALSE(g.closed()(2, 3));  // grains never count as deposit
  EXPECT_NEAR(g.depositedVolume(), 3.5 * cap, 1e-12 * cap);
}

TEST(Micromodel, PassableDiameterOfStraightChannelsAndAThroat) {
  const double px = 2e-6;
  // A channel of 7 open rows between solid rows: 7 pixels wide. (Distances are
  // sampled at pixel centres, so an odd width is exact and an even width n reads
  // n - 1: the resolution of the image, stated in the header.)
  PixelMask m = PixelMask::Constant(11, 20, true);
  m.block(2, 0, 7, 20) = false;
  EXPECT_NEAR(passableDiameter(m, px), 7 * px, 1e-9 * px);
  EXPECT_NEAR(inletOpening(m, px), 7 * px, 1e-9 * px);
  // Narrowed to 3 rows over columns 8-11: the bottleneck is the throat.
  m.block(2, 8, 4, 4) = true;
  EXPECT_NEAR(passableDiameter(m, px), 3 * px, 1e-9 * px);
  EXPECT_NEAR(inletOpening(m, px), 7 * px, 1e-9 * px);
  // Closed: no path.
  m.block(2, 8, 7, 4) = true;
  EXPECT_EQ(passableDiameter(m, px), 0.0);
}

SceneConfig colloidScene(std::uint64_t seed) {
  SceneConfig c;
  c.seed = seed;
  c.brownian = true;
  c.attachment.hamaker = 1e-20;
  return c;
}

std::vector<Vec3> somePositions(int n, double x0) {
  std::vector<Vec3> p;
  for (int i = 0; i < n; ++i) p.emplace_back(x0 + 7e-6 * (i % 10), 20e-6 + 9e-6 * (i / 10), 4e-6 + 1.2e-6 * (i % 9));
  return p;
}

TEST(Micromodel, EngineRestoredFromCheckpointContinuesBitForBit) {
  auto flow = std::make_shared<HeleShawChannel>(2e-3, 200e-6, 20e-6, 0.7e-3);
  OverdampedEngine a(flow, colloidScene(3));
  a.insert(somePositions(60, 10e-6));
  a.advance(0.4);
  CheckpointWriter w;
  a.saveState(w);
  a.advance(1.2);
  OverdampedEngine b(flow, colloidScene(99));  // another seed: the state must carry the generator
  CheckpointReader r(w.bytes(), "memory");
  b.loadState(r);
  b.advance(1.2);
  const auto pa = a.particles(), pb = b.particles();
  ASSERT_EQ(pa.size(), pb.size());
  int deposited = 0;
  for (std::size_t i = 0; i < pa.size(); ++i) {
    // Bitwise identity is the property under test (same operations in the same order).
    EXPECT_EQ(pa[i].x.x(), pb[i].x.x());
    EXPECT_EQ(pa[i].x.y(), pb[i].x.y());
    EXPECT_EQ(pa[i].x.z(), pb[i].x.z());
    EXPECT_EQ(pa[i].status, pb[i].status);
    deposited += pa[i].status == ParticleStatus::deposited;
  }
  EXPECT_GT(deposited, 0);  // the window covers deposition, so the restored deposit index matters
  EXPECT_EQ(a.stats().steps, b.stats().steps);
  CheckpointReader bad(w.bytes().substr(0, 40), "truncated");
  OverdampedEngine c(flow, colloidScene(3));
  EXPECT_THROW(c.loadState(bad), std::runtime_error);
}

TEST(Micromodel, SameSeedSameTrajectoriesOtherSeedDifferent) {
  auto flow = std::make_shared<HeleShawChannel>(2e-3, 200e-6, 20e-6, 0.7e-3);
  OverdampedEngine a(flow, colloidScene(5)), b(flow, colloidScene(5)), c(flow, colloidScene(6));
  for (auto* e : {&a, &b, &c}) {
    e->insert(somePositions(30, 10e-6));
    e->advance(0.5);
  }
  const auto pa = a.particles(), pb = b.particles(), pc = c.particles();
  double diff_c = 0;
  for (std::size_t i = 0; i < pa.size(); ++i) {
    EXPECT_EQ(pa[i].x.x(), pb[i].x.x());
    EXPECT_EQ(pa[i].x.z(), pb[i].x.z());
    diff_c = std::max(diff_c, (pa[i].x - pc[i].x).norm());
  }
  EXPECT_GT(diff_c, 1e-9);  // Brownian motion is on: another seed moves them differently
}

TEST(MicromodelBadInput, OverlappingInsertionIsRefusedWholesale) {
  auto flow = std::make_shared<HeleShawChannel>(2e-3, 200e-6, 20e-6, 0.7e-3);
  OverdampedEngine e(flow, colloidScene(1));
  try {
    e.insert({Vec3(50e-6, 50e-6, 10e-6), Vec3(53e-6, 50e-6, 10e-6)});  // 3 um apart, diameter 5 um
    FAIL() << "overlap accepted";
  } catch (const InputError& err) {
    EXPECT_NE(std::string(err.what()).find("overlaps particle 1"), std::string::npos) << err.what();
    EXPECT_NE(std::string(err.what()).find("particles.insert"), std::string::npos) << err.what();
  }
  EXPECT_EQ(e.counts().injected, 0);  // nothing inserted
  // The inlet sampler never overlaps, and says clearly when the strip is too full.
  const auto pos = sampleInlet(*flow, 2.5e-6, 0.0, 50e-6, 40, 11, {});
  for (std::size_t i = 0; i < pos.size(); ++i)
    for (std::size_t j = i + 1; j < pos.size(); ++j) EXPECT_GE((pos[i] - pos[j]).norm(), 5e-6 * (1 - 1e-12));
  EXPECT_THROW(sampleInlet(*flow, 2.5e-6, 0.0, 5e-6, 200, 11, {}), InputError);  // ~40 fit in a 5 um strip
}

TEST(MicromodelBadInput, InsertionIntoAGrainIsRefused) {
  const int nx = 40, ny = 20;
  const double dx = 2e-6;
  std::vector<std::uint8_t> s(nx * ny, 0);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < 6; ++i) s[j * nx + i] = j < 10;  // a grain over the lower half of the inlet
  std::vector<double> ux(nx * ny, 1e-4), uy(nx * ny, 0.0), h(nx * ny, 20e-6);
  auto g = std::make_shared<GriddedFlow>(nx, ny, 0, 0, dx, dx);
  g->update(ux, uy, h, s);
  OverdampedEngine e(g, colloidScene(1));
  EXPECT_THROW(e.insert({Vec3(4e-6, 6e-6, 10e-6)}), InputError);
  // The sampler places particles only in the open half, at least a radius from the grain.
  const auto pos = sampleInlet(*g, 2.5e-6, 0.0, 8e-6, 6, 3, {});
  for (const auto& p : pos) {
    EXPECT_FALSE(g->isSolid(p.x(), p.y()));
    EXPECT_GE(g->wallDistance(p.x(), p.y()), 2.5e-6 * (1 - 1e-9));
  }
}

/// A straight channel whose open width is exactly one particle diameter.
std::shared_ptr<GriddedFlow> oneDiameterChannel(double d, int open_rows) {
  const int nx = 60, ny = open_rows + 2;
  const double dx = d / open_rows;
  std::vector<std::uint8_t> s(nx * ny, 0);
  for (int i = 0; i < nx; ++i) s[i] = s[(ny - 1) * nx + i] = 1;
  std::vector<double> ux(nx * ny, 0.5e-3), uy(nx * ny, 0.0), h(nx * ny, 20e-6);
  for (int i = 0; i < nx; ++i) ux[i] = ux[(ny - 1) * nx + i] = 0.0;
  auto g = std::make_shared<GriddedFlow>(nx, ny, 0, -dx, dx, dx);  // walls at y = -dx/2 ... wall between nodes
  g->update(ux, uy, h, s);
  return g;
}

TEST(MicromodelBadInput, ThroatExactlyOneParticleWide) {
  const double d = 5e-6;
  auto g = oneDiameterChannel(d, 5);  // fluid nodes at y = 0 .. 4 dx: walls at y = -dx/2 and 4.5 dx, width 5 dx = d
  const double yc = 2 * d / 5;        // centre line
  EXPECT_NEAR(g->wallDistance(10 * d / 5, yc), 0.5 * d, 1e-12);
  // Non-sticky walls: the particle fits exactly, touches both walls and is carried out.
  SceneConfig free = colloidScene(1);
  free.brownian = false;
  free.attachment.capture_distance = 0.0;
  free.attachment.hamaker = 0.0;
  free.gravity = 0.0;
  OverdampedEngine e(g, free);
  e.insert({Vec3(5e-6, yc, 10e-6)});
  e.advance(1.0);
  EXPECT_EQ(e.counts().left, 1) << "x = " << e.particles()[0].x.x();
  // Sticky walls: the gap to both walls is zero, so it attaches where it was put.
  SceneConfig sticky = free;
  sticky.attachment.capture_distance = 0.1e-6;
  OverdampedEngine f(g, sticky);
  f.insert({Vec3(5e-6, yc, 10e-6)});
  f.advance(0.1);
  EXPECT_EQ(f.counts().deposited, 1);
  EXPECT_LT(f.particles()[0].x.x(), 5e-6 + 0.5 * d);
}

}  // namespace
}  // namespace mmval::particles
