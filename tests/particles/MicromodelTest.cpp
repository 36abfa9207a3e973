// Pieces of the coupled micromodel scene (issue 6), each against an
// independent reference: the distance transform against brute force, deposit
// volume conservation (columns and plate layers), the flux through thinned
// apertures (Reynolds equation), throat bottlenecks of masks with known widths, engine
// checkpoints against uninterrupted runs, and bad insertions.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "mmval/core/Error.hpp"
#include "mmval/particles/DepositGrid.hpp"
#include "mmval/particles/HydroModel.hpp"
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

TEST(Micromodel, PlateLayerThinsTheApertureAndConservesVolume) {
  // 5 x 5 pore pixels of 10 um, 20 um deep, 5 um particles: a monolayer (5 um of
  // layer at packing phi) holds phi * px^2 * 5 um of solid per pixel.
  const PixelMask grains = PixelMask::Constant(5, 5, false);
  const double px = 10e-6, h = 20e-6, d = 5e-6;
  DepositLayerModel lm;  // default packing: RSA jamming 0.547 x 2/3
  lm.min_aperture = d;
  EXPECT_NEAR(lm.packing, 0.547 * 2.0 / 3.0, 1e-15);
  DepositGrid g(grains, px, h, 0.5, lm);
  const double mono = lm.packing * px * px * d;
  // 3.5 monolayers at the centre: one each to the centre and to its nearest
  // neighbours (distance 1, ties by index: up, left, then half to right).
  EXPECT_EQ(g.addLayer(2.5 * px, 2.5 * px, 3.5 * mono, d), 0);
  const std::vector<double> a = g.aperture();
  const auto at = [&](int r, int c) { return a[static_cast<std::size_t>(r * 5 + c)]; };
  EXPECT_NEAR(at(2, 2), h - d, 1e-12 * h);
  EXPECT_NEAR(at(1, 2), h - d, 1e-12 * h);
  EXPECT_NEAR(at(2, 1), h - d, 1e-12 * h);
  EXPECT_NEAR(at(2, 3), h - 0.5 * d, 1e-12 * h);
  EXPECT_NEAR(at(3, 2), h, 1e-12 * h);
  EXPECT_NEAR(g.lostColumns(), 3.5 * d / h, 1e-12);  // lost aperture in whole columns
  EXPECT_NEAR(g.depositedVolume(), 3.5 * mono, 1e-12 * mono);
  // Two more at the centre: the centre reaches 15 um of layer (aperture = min_aperture = d) and closes.
  EXPECT_EQ(g.addLayer(2.5 * px, 2.5 * px, mono, d), 0);
  EXPECT_EQ(g.addLayer(2.5 * px, 2.5 * px, mono, d), 1);
  EXPECT_TRUE(g.closed()(2, 2));
  EXPECT_EQ(g.aperture()[12], 0.0);
  // Lost columns: the closed pixel counts 1; the others their layer / depth.
  double layer_sum = 0;
  for (std::size_t k = 0; k < 25; ++k)
    if (k != 12) layer_sum += h - g.aperture()[k];
  EXPECT_NEAR(g.lostColumns(), 1.0 + layer_sum / h, 1e-12);
  // Column deposits alone: lost columns = closed pixels exactly (the re-solve trigger of column mode).
  DepositGrid col(grains, px, h, 0.5, lm);
  col.add(2.5 * px, 2.5 * px, 3.5 * col.capacity());
  EXPECT_EQ(col.lostColumns(), static_cast<double>(col.closedCount()));
  EXPECT_THROW(DepositGrid(grains, px, h, 0.5, DepositLayerModel{0.4, h}), std::invalid_argument);
}

TEST(Micromodel, FlowThroughThinnedAperturesFollowsTheReynoldsEquation) {
  // An open 20 x 10 px slot (10 um px, 20 um deep, slip sides): k = h^3 / (12 h_ref)
  // with q per unit reference depth; uniform flow has no in-plane shear, so
  // these are exact (round-off tolerance).
  const PixelMask open = PixelMask::Constant(10, 20, false);
  MicromodelFlowOptions o;
  o.pixel = 10e-6;
  o.depth = 20e-6;
  o.darcy_velocity = 1e-4;
  MicromodelFlow flow(open, o);
  const double k0 = flow.solve({}).permeability;
  EXPECT_NEAR(k0 / (o.depth * o.depth / 12), 1.0, 1e-10);
  // Half the aperture everywhere: k / 8.
  std::vector<double> ap(200, 10e-6);
  EXPECT_NEAR(flow.solve({}, ap).permeability / k0, 1.0 / 8.0, 1e-10);
  EXPECT_NEAR(flow.field()->depth(55e-6, 45e-6), 10e-6, 1e-18);  // the engines see the thinned aperture
  // Downstream half at 10 um (a step at a fluid cell face): resistances in series,
  // k / k0 = 1 / (0.5 + 0.5 * 8).
  for (int r = 0; r < 10; ++r)
    for (int c = 0; c < 20; ++c) ap[static_cast<std::size_t>(r * 20 + c)] = c < 10 ? 20e-6 : 10e-6;
  EXPECT_NEAR(flow.solve({}, ap).permeability / k0, 1.0 / 4.5, 1e-10);
  EXPECT_THROW(flow.solve({}, std::vector<double>(3, 1e-6)), std::invalid_argument);
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

TEST(Micromodel, PlateTorqueBalanceAgainstItsClosedForm) {
  // A 5 um polystyrene sphere on the bottom plate of a 20 um Hele-Shaw channel:
  // it stays when the DMT adhesion torque (F_A + W) (F_A + W)^(1/3) (a / K)^(1/3)
  // exceeds the Goldman-Cox-Brenner moment a (1.7009 6 pi mu a^2 + 0.944 4 pi mu a^2) G,
  // G = 6 u_mean / h. Critical mean speed by hand: ~3.0 mm/s for A = 1e-20 J,
  // z0 = 0.4 nm, K = 4.84 GPa.
  const double h = 20e-6, a = 2.5e-6, mu = 1e-3;
  SceneConfig c = colloidScene(1);
  c.attachment.torque_balance = true;
  const double fa = c.attachment.hamaker * a / (6 * std::pow(c.attachment.adhesion_separation, 2));
  const double w = (c.particle.density - c.fluid.density) * c.particle.volume() * c.gravity;
  const double load = fa + w, resisting = load * std::cbrt(load * a / c.attachment.contact_modulus);
  const double g_c = resisting / (a * (1.7009 * 6 * kPi * mu * a * a + 0.944 * 4 * kPi * mu * a * a));
  const double u_c = g_c * h / 6;
  EXPECT_NEAR(u_c, 3.008e-3, 1e-5);
  for (double f : {0.95, 1.05}) {
    auto flow = std::make_shared<HeleShawChannel>(2e-3, 200e-6, h, f * u_c);
    HydroModel m(flow, c);
    double margin = 0;
    EXPECT_EQ(m.plateAdhesionHolds(Vec3(1e-3, 100e-6, a), true, &margin), f < 1) << f;
    EXPECT_NEAR(margin, 1 / f, 1e-12);  // the moments are linear in the shear rate
  }
  // In the engine: particles resting on the bottom at 3 u_c roll on (torque
  // balance) instead of sticking (capture rule).
  auto fast = std::make_shared<HeleShawChannel>(2e-3, 200e-6, h, 3 * u_c);
  int stuck[2] = {0, 0};
  for (int rule = 0; rule < 2; ++rule) {
    SceneConfig sc = colloidScene(2);
    sc.attachment.torque_balance = rule == 1;
    sc.attachment.grains = false;  // plates only
    OverdampedEngine e(fast, sc);
    std::vector<Vec3> pos;
    for (int i = 0; i < 20; ++i) pos.emplace_back(20e-6 + 8e-6 * (i % 5), 40e-6 + 30e-6 * (i / 5), a + 0.05e-6);
    e.insert(pos);
    e.advance(0.05);
    stuck[rule] = static_cast<int>(e.counts().deposited);
  }
  EXPECT_EQ(stuck[0], 20);  // inside the capture distance (0.1 um): all captured at the first step
  EXPECT_EQ(stuck[1], 0);
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
