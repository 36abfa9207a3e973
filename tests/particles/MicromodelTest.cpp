// Pieces of the coupled micromodel scene, each against an
// independent reference: the distance transform against brute force, deposit
// volume conservation (columns and plate layers), the flux through thinned
// apertures (Reynolds equation), throat bottlenecks of masks with known widths, engine
// checkpoints against uninterrupted runs, and bad insertions; the run's stages
// (insertion, deposition, re-solve, frame record) each alone.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <random>
#include <string>

#include <petscsys.h>

#include "mmval/core/Error.hpp"
#include "mmval/particles/DepositGrid.hpp"
#include "mmval/particles/HydroModel.hpp"
#include "mmval/particles/MicromodelFlow.hpp"
#include "mmval/particles/OverdampedEngine.hpp"
// The micromodel run's stages are internal to the library (no public header).
#include "MicromodelStages.hpp"

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

/// An open slot's flow options: 10 um pixels, 20 um deep, Darcy velocity 0.1 mm/s.
MicromodelFlowOptions slotOptions() {
  MicromodelFlowOptions o;
  o.pixel = 10e-6;
  o.depth = 20e-6;
  o.darcy_velocity = 1e-4;
  return o;
}

TEST(Micromodel, FlowThroughThinnedAperturesFollowsTheReynoldsEquation) {
  // An open 20 x 10 px slot (10 um px, 20 um deep, slip sides): k = h^3 / (12 h_ref)
  // with q per unit reference depth; uniform flow has no in-plane shear, so
  // these are exact (round-off tolerance).
  const PixelMask open = PixelMask::Constant(10, 20, false);
  const MicromodelFlowOptions o = slotOptions();
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

TEST(Micromodel, ALuThatCannotFactoriseHandsTheRunToTheFrictionSplit) {
  // The micromodel picks its linear solver itself (no numerics.linear_solver key in this kind). A
  // direct LU its library cannot factorise (UMFPACK out of memory at 1.69M unknowns, Pore2Chip at
  // 1.5 cells per pixel; here MUMPS starved to 1 MB of working memory by PETSc options) hands that
  // solve and every later one to the friction split (FGMRES to a relative residual of 1e-12), whose
  // permeability equals the unstarved LU's to 1e-8 (two LUs ordered differently differ by ~1e-8 of
  // the largest velocity); a re-solve with a deposit and thinner apertures agrees as well.
  // 60 x 120 px of 10 um with 12 square grains, 1 cell per pixel: 7,200 cells, under the
  // friction split's 40,000 (so the LU is tried first), over what 1 MB factorises.
  PixelMask grains = PixelMask::Constant(60, 120, false);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) grains.block(6 + 18 * r, 10 + 28 * c + 5 * r, 10, 12) = true;
  MicromodelFlowOptions o = slotOptions();
  o.cells_per_pixel = 1;
  PixelMask deposit = PixelMask::Constant(60, 120, false);
  deposit.block(16, 22, 3, 3) = true;  // beside the first grain
  const std::vector<double> thinner(60 * 120, 15e-6);
  MicromodelFlow lu(grains, o);
  const FlowSolveResult a = lu.solve({});
  const FlowSolveResult b = lu.solve(deposit, thinner);
  ASSERT_TRUE(a.factorised);
  ASSERT_GT(a.permeability, b.permeability);
  PetscOptionsSetValue(nullptr, "-fluid_pc_factor_mat_solver_type", "mumps");
  PetscOptionsSetValue(nullptr, "-fluid_mat_mumps_icntl_23", "1");
  MicromodelFlow starved(grains, o);
  const FlowSolveResult sa = starved.solve({});
  const FlowSolveResult sb = starved.solve(deposit, thinner);
  PetscOptionsClearValue(nullptr, "-fluid_pc_factor_mat_solver_type");
  PetscOptionsClearValue(nullptr, "-fluid_mat_mumps_icntl_23");
  EXPECT_FALSE(sa.factorised);
  EXPECT_FALSE(sb.factorised);
  EXPECT_GT(sa.iterations, 1);  // FGMRES iterations, not an LU solve
  EXPECT_GT(sb.iterations, 1);
  EXPECT_NEAR(sa.permeability / a.permeability, 1.0, 1e-8);
  EXPECT_NEAR(sb.permeability / b.permeability, 1.0, 1e-8);
  // The engines' field too: a pixel-face velocity in a throat.
  const Vec2 ua = lu.field()->meanVelocity(250e-6, 395e-6), ub = starved.field()->meanVelocity(250e-6, 395e-6);
  EXPECT_GT(std::hypot(ua.x(), ua.y()), 0.0);
  EXPECT_NEAR(ub.x(), ua.x(), 1e-7 * std::hypot(ua.x(), ua.y()));
  EXPECT_NEAR(ub.y(), ua.y(), 1e-7 * std::hypot(ua.x(), ua.y()));
}

TEST(Micromodel, AGridTooLargeForTheLuGoesStraightToTheFrictionSplit) {
  // The linear solver picked up front for the scene's grids (cases/particles-micromodel-full.toml:
  // the Pore2Chip mask, 10 um pixels, 20 um deep). Reference: the rule before the size limit,
  // restated here (the friction split where the grid has 40,000 cells or more and 12 / h^2 is at
  // least half of 2 / dx^2 + 2 / dy^2, else the LU), and the staggered grid's unknowns counted
  // directly (u on (nx + 1) x ny faces, v on nx x (ny + 1), p on nx x ny cells).
  // The mask's size from its PNG header (IHDR: width and height, big-endian, at bytes 16-23).
  std::ifstream png(std::string(MMVAL_SHARED_DATA_DIR) + "/pore2chip/grain_network.png", std::ios::binary);
  unsigned char ihdr[24] = {};
  ASSERT_TRUE(png.read(reinterpret_cast<char*>(ihdr), sizeof ihdr));
  const auto be32 = [&](int at) {
    long long v = 0;
    for (int k = 0; k < 4; ++k) v = v * 256 + ihdr[at + k];
    return v;
  };
  const long long cols = be32(16), rows = be32(20);
  const double pixel = 10e-6, depth = 20e-6;
  const auto frictionPicksSplit = [&](long long nx, long long ny, double dx, double dy) {
    return nx * ny >= 40000 && 12 / (depth * depth) >= 0.5 * (2 / (dx * dx) + 2 / (dy * dy));
  };
  const auto grid = [&](double cells_per_pixel, long long& nx, long long& ny, double& dx, double& dy) {
    nx = std::lround(static_cast<double>(cols) * cells_per_pixel);
    ny = std::lround(static_cast<double>(rows) * cells_per_pixel);
    dx = static_cast<double>(cols) * pixel / static_cast<double>(nx);
    dy = static_cast<double>(rows) * pixel / static_cast<double>(ny);
  };
  long long nx = 0, ny = 0;
  double dx = 0, dy = 0;
  // 1.5 cells per pixel: 750 x 750 cells, 1.69M unknowns (where UMFPACK failed), cells 0.33 of the
  // depth: friction alone picks the LU; the size sends it to the split with the fallback's budget.
  grid(1.5, nx, ny, dx, dy);
  ASSERT_EQ(nx, 750);
  ASSERT_EQ(ny, 750);
  ASSERT_FALSE(frictionPicksSplit(nx, ny, dx, dy));
  const FluidSolverChoice fine = fluidSolverChoice(nx, ny, dx, dy, depth);
  EXPECT_EQ(fine.unknowns, 751LL * 750 + 750LL * 751 + 750LL * 750);
  EXPECT_TRUE(fine.split);
  EXPECT_TRUE(fine.lu_too_large);
  EXPECT_EQ(fine.max_iterations, 400);  // kSplitFallbackMaxIterations, what the run took after the failed LU
  EXPECT_GT(fine.lu_bytes, 4.4e9);      // the failed LU's measured peak
  // 1, 0.75 and 0.5 cells per pixel: the split as before, with its own 60 iterations, not for size.
  for (const double cpp : {1.0, 0.75, 0.5}) {
    grid(cpp, nx, ny, dx, dy);
    ASSERT_TRUE(frictionPicksSplit(nx, ny, dx, dy)) << cpp;
    const FluidSolverChoice c = fluidSolverChoice(nx, ny, dx, dy, depth);
    EXPECT_TRUE(c.split) << cpp;
    EXPECT_FALSE(c.lu_too_large) << cpp;
    EXPECT_EQ(c.max_iterations, 60) << cpp;
  }
  // The case file's 200 x 150 px window (cases/particles-micromodel.toml) keeps the LU at 1.5 cells
  // per pixel (203k unknowns) and at 4 (1.44M unknowns, measured to factorise in 3.8 GB).
  for (const double cpp : {1.5, 4.0}) {
    const long long wx = std::lround(200 * cpp), wy = std::lround(150 * cpp);
    const double d = pixel / cpp;
    ASSERT_FALSE(frictionPicksSplit(wx, wy, d, d)) << cpp;
    const FluidSolverChoice c = fluidSolverChoice(wx, wy, d, d, depth);
    EXPECT_FALSE(c.split) << cpp;
    EXPECT_EQ(c.max_iterations, 0) << cpp;
  }
  // A tiny grid (the slot of FlowThroughThinnedApertures..., 20 x 10 cells) keeps the LU, and so
  // does a grid under 40,000 cells whatever the friction.
  EXPECT_FALSE(fluidSolverChoice(20, 10, 10e-6, 10e-6, depth).split);
  MicromodelFlow slot(PixelMask::Constant(10, 20, false), slotOptions());
  EXPECT_EQ(slot.linearSolver(), "");
  slot.solve({});
  EXPECT_EQ(slot.linearSolver(), "direct LU");
  EXPECT_FALSE(fluidSolverChoice(199, 200, 10e-6, 10e-6, depth).split);
  // Coarse cells on the same 1.69M unknowns: friction dominates, the split with its own budget.
  const FluidSolverChoice coarse = fluidSolverChoice(750, 750, 20e-6, 20e-6, depth);
  EXPECT_TRUE(coarse.split);
  EXPECT_FALSE(coarse.lu_too_large);
  EXPECT_EQ(coarse.max_iterations, 60);
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

TEST(Micromodel, SurfaceTorqueBalanceHoldsOnlyWhereTheFlowIsSlow) {
  // A 5 um polystyrene sphere touching a side wall of a 20 um Hele-Shaw channel at mid-depth
  // (walls count as grains). Held when the DMT contact adhesion torque F (F a / K)^(1/3),
  // F = A a / (6 z0^2), exceeds the Goldman-Cox-Brenner moment a (1.7009 6 pi mu a^2 + 0.944 4 pi
  // mu a^2) G with G = u / a, u the fluid speed at its centre. Against a deposit F uses a / 2.
  // By hand for A = 1e-20 J, z0 = 0.4 nm, K = 4.84 GPa: F = 26.04 nN, critical u = 2.26 mm/s.
  const double h = 20e-6, a = 2.5e-6, mu = 1e-3;
  SceneConfig c = colloidScene(1);
  c.attachment.surface_torque_balance = true;
  const double fa = 1e-20 * a / (6 * 0.4e-9 * 0.4e-9);
  const auto critical = [&](double f) { return f * std::cbrt(f * a / 4.84e9) / (1.7009 * 6 * kPi * mu * a * a + 0.944 * 4 * kPi * mu * a * a); };
  const double u_c = critical(fa);
  EXPECT_NEAR(u_c, 2.256e-3, 1e-6);
  const Vec3 x(1e-3, a + 0.05e-6, 0.5 * h);
  {
    auto probe = std::make_shared<HeleShawChannel>(2e-3, 200e-6, h, 1e-3);
    HydroModel m(probe, c);
    EXPECT_NEAR(m.contactAdhesion(false), fa, 1e-12 * fa);
    EXPECT_NEAR(m.contactAdhesion(true), 0.5 * fa, 1e-12 * fa);
  }
  // The flow that puts the centre's speed at f u_c: the depth profile at mid-depth over the mean.
  const double per_mean = [&] {
    auto unit = std::make_shared<HeleShawChannel>(2e-3, 200e-6, h, 1.0);
    return HydroModel(unit, c).fluidVelocity(x).norm();
  }();
  EXPECT_NEAR(per_mean, 1.5 - 2 * a * a / (h * h), 1e-9);  // Poiseuille at mid-depth, Faxen's a^2/6 term
  for (double f : {0.9, 1.1}) {
    auto flow = std::make_shared<HeleShawChannel>(2e-3, 200e-6, h, f * u_c / per_mean);
    HydroModel m(flow, c);
    double margin = 0;
    EXPECT_EQ(m.surfaceAdhesionHolds(x, m.contactAdhesion(false), &margin), f < 1) << f;
    EXPECT_NEAR(margin, 1 / f, 1e-9);
  }
  // In the engine, grains (the side walls) sticky, plates not: at 0.5 u_c every particle touching
  // the wall is held at once; at 2 u_c none is under the torque balance, all under the capture rule.
  int held[3] = {0, 0, 0};
  for (int run = 0; run < 3; ++run) {
    SceneConfig sc = colloidScene(2);
    sc.attachment.bottom = false;
    sc.attachment.deposited = false;
    sc.attachment.surface_torque_balance = run > 0;
    const double u = (run == 2 ? 0.5 : 2.0) * u_c / per_mean;
    auto flow = std::make_shared<HeleShawChannel>(2e-3, 200e-6, h, u);
    OverdampedEngine e(flow, sc);
    std::vector<Vec3> pos;
    for (int i = 0; i < 10; ++i) pos.emplace_back(20e-6 + 12e-6 * i, a + 0.05e-6, 0.5 * h);
    for (int i = 0; i < 10; ++i) pos.emplace_back(20e-6 + 12e-6 * i, 200e-6 - a - 0.05e-6, 0.5 * h);
    e.insert(pos);
    e.advance(0.02);
    held[run] = static_cast<int>(e.counts().deposited);
  }
  EXPECT_EQ(held[0], 20);  // capture rule, fast flow: every contact holds
  EXPECT_EQ(held[1], 0);   // torque balance, fast flow: none
  EXPECT_EQ(held[2], 20);  // torque balance, slow flow: all
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

// --- The run's stages alone (MicromodelStages.hpp) ---

SceneConfig stageScene(double diameter, std::uint64_t seed) {
  SceneConfig c = colloidScene(seed);
  c.particle.diameter = diameter;
  return c;
}

TEST(MicromodelStages, InsertDuePlacesTheScheduleInTheStripAndNumbersInOrder) {
  // Two classes taking 3/4 and 1/4 of 40 particles per second: by t = 1 s the
  // schedule calls for floor(30) and floor(10), by 1.5 s for 45 and 15. Ids run
  // over the classes in injection order; every centre lies in the strip
  // [a, a + strip] (sampleInlet's contract), a = the radius.
  auto flow = std::make_shared<HeleShawChannel>(2e-3, 200e-6, 20e-6, 0.7e-3);
  std::vector<stages::SizeClass> classes(2);
  classes[0].diameter = 5e-6;
  classes[0].fraction = 0.75;
  classes[1].diameter = 3e-6;
  classes[1].fraction = 0.25;
  stages::makeEngines(classes, flow, stageScene(5e-6, 4), 4);
  stages::Schedule sch;
  sch.rate_per_s = 40;
  sch.injection_time = 10;
  sch.strip = 100e-6;
  sch.max_strip = 1e-3;
  sch.seed = 4;
  stages::ClassParticles ps(2);
  std::int64_t next_id = 1;
  stages::insertDue(classes, *flow, sch, 1, 1.0, ps, next_id);
  EXPECT_EQ(classes[0].injected, 30);
  EXPECT_EQ(classes[1].injected, 10);
  EXPECT_EQ(next_id, 41);
  stages::insertDue(classes, *flow, sch, 2, 1.5, ps, next_id);
  ASSERT_EQ(ps[0].size(), 45u);
  ASSERT_EQ(ps[1].size(), 15u);
  EXPECT_EQ(next_id, 61);
  // Frame 1: class 0 ids 1..30, class 1 ids 31..40; frame 2: class 0 41..55, class 1 56..60.
  EXPECT_EQ(classes[0].global_id[0], 1);
  EXPECT_EQ(classes[0].global_id[29], 30);
  EXPECT_EQ(classes[1].global_id[0], 31);
  EXPECT_EQ(classes[0].global_id[30], 41);
  EXPECT_EQ(classes[1].global_id[14], 60);
  for (std::size_t ci = 0; ci < 2; ++ci) {
    EXPECT_EQ(classes[ci].deferred, 0);
    EXPECT_EQ(classes[ci].accounted.size(), ps[ci].size());
    const double a = 0.5 * classes[ci].diameter;
    for (const auto& p : ps[ci]) {
      EXPECT_GE(p.x.x(), a - 1e-15);
      EXPECT_LE(p.x.x(), a + sch.strip + 1e-15);
    }
  }
}

TEST(MicromodelStages, InsertDueDefersWhatAFullStripCannotTake) {
  // 300 particles of 5 um due at once into a strip one diameter long across a
  // 50 x 20 um channel: centres in x in [a, a + d], so the spheres lie in a box
  // 2d x 50 um x 20 um, which holds at most 0.7405 of its volume in spheres
  // (Kepler's bound, Hales 2005): 113 particles. The rest waits for the next frame.
  auto flow = std::make_shared<HeleShawChannel>(2e-3, 50e-6, 20e-6, 0.7e-3);
  const double d = 5e-6;
  std::vector<stages::SizeClass> classes(1);
  classes[0].diameter = d;
  stages::makeEngines(classes, flow, stageScene(d, 2), 2);
  stages::Schedule sch;
  sch.rate_per_s = 300;
  sch.injection_time = 10;
  sch.strip = 0;  // widened to one diameter by the stage
  sch.max_strip = 1e-3;
  sch.seed = 2;
  stages::ClassParticles ps(1);
  std::int64_t next_id = 1;
  stages::insertDue(classes, *flow, sch, 1, 1.0, ps, next_id);
  const double bound = 0.7405 * (2 * d * 50e-6 * 20e-6) / (kPi * d * d * d / 6);
  EXPECT_GT(classes[0].injected, 0);
  EXPECT_LE(static_cast<double>(classes[0].injected), bound);
  EXPECT_EQ(classes[0].deferred, 300 - classes[0].injected);
  EXPECT_EQ(next_id, classes[0].injected + 1);
  EXPECT_EQ(static_cast<std::int64_t>(ps[0].size()), classes[0].injected);
}

TEST(MicromodelStages, DeferredParticlesArePlacedOnceTheStripClears) {
  // A crowded inlet frame after frame: 120 particles of 5 um due at once into
  // the one-diameter strip of a 50 x 20 um channel, which takes only a few tens
  // per frame (random placement with 1000 tries per particle jams far below
  // close packing). No attachment, attraction, settling or Brownian motion, so
  // each particle moves with the flow at its height (u_mean = 0.7 mm/s: tens of
  // um per 0.2 s frame even beside a plate) and clears the strip. Every particle
  // due is placed within twelve frames, numbered once, and counted as
  // injected = inside + left (nothing deposits); until then injected + deferred
  // is the schedule, so none is dropped.
  auto flow = std::make_shared<HeleShawChannel>(2e-3, 50e-6, 20e-6, 0.7e-3);
  const double d = 5e-6;
  const std::int64_t due = 120;
  SceneConfig scene = stageScene(d, 2);
  scene.brownian = false;
  scene.gravity = 0;
  scene.attachment.capture_distance = 0;
  scene.attachment.hamaker = 0;
  std::vector<stages::SizeClass> classes(1);
  classes[0].diameter = d;
  stages::makeEngines(classes, flow, scene, 2);
  stages::Schedule sch;
  sch.rate_per_s = static_cast<double>(due);
  sch.injection_time = 1;  // all due by the first frame
  sch.strip = 0;           // widened to one diameter by the stage
  sch.max_strip = 1e-3;
  sch.seed = 2;
  stages::ClassParticles ps(1);
  std::int64_t next_id = 1;
  int frames_with_deferral = 0;
  for (std::int64_t k = 1; k <= 12; ++k) {
    const double t = 1.0 + 0.2 * static_cast<double>(k - 1);
    ps = stages::transport(classes, k, t);
    stages::insertDue(classes, *flow, sch, k, t, ps, next_id);
    if (classes[0].deferred > 0) ++frames_with_deferral;
    EXPECT_EQ(classes[0].injected + classes[0].deferred, due) << "frame " << k;
  }
  EXPECT_GE(frames_with_deferral, 2);  // the inlet was crowded: the test exercises deferral
  EXPECT_EQ(classes[0].injected, due);
  EXPECT_EQ(classes[0].deferred, 0);
  EXPECT_EQ(next_id, due + 1);
  ASSERT_EQ(static_cast<std::int64_t>(ps[0].size()), due);
  std::vector<std::int64_t> ids = classes[0].global_id;
  std::sort(ids.begin(), ids.end());
  for (std::size_t i = 0; i < ids.size(); ++i) EXPECT_EQ(ids[i], static_cast<std::int64_t>(i) + 1);
  const Counts n = countParticles(ps[0]);
  EXPECT_EQ(n.injected, due);
  EXPECT_EQ(n.deposited, 0);
  EXPECT_EQ(n.inside + n.left, due);
}

TEST(MicromodelStages, DepositBooksEachNewDepositOnceAtItsParcelVolume) {
  // A 20 x 20 px chip (10 um px, 20 um deep) with a 4 x 4 px grain at its centre
  // (x, y in [80, 120] um). A deposit 2.5 um from the grain's face (below one
  // diameter) fills columns; one 45 um from every wall lies on the plate and
  // thins the aperture. Each books weight x pi d^3 / 6, once.
  PixelMask grains = PixelMask::Constant(20, 20, false);
  grains.block(8, 8, 4, 4).setConstant(true);
  MicromodelFlowOptions o;
  o.pixel = 10e-6;
  o.depth = 20e-6;
  o.darcy_velocity = 1e-4;
  MicromodelFlow flow(grains, o);
  flow.solve({});
  const double d = 5e-6, weight = 20, vol = weight * kPi * d * d * d / 6;
  stages::Coupling cp;
  cp.weight = weight;
  cp.layers = true;
  DepositGrid deposits(grains, o.pixel, o.depth, 0.5, DepositLayerModel{0.365, d});
  std::vector<stages::SizeClass> classes(1);
  classes[0].diameter = d;
  classes[0].accounted.assign(3, 0);
  stages::ClassParticles ps(1, std::vector<ParticleState>(3));
  ps[0][0].x = Vec3(122.5e-6, 100e-6, 2.5e-6);  // at the grain
  ps[0][1].x = Vec3(50e-6, 55e-6, 2.5e-6);     // on the plate
  ps[0][2].x = Vec3(150e-6, 150e-6, 8e-6);     // still moving
  ps[0][0].status = ps[0][1].status = ParticleStatus::deposited;
  std::int64_t at_walls = 0, on_plates = 0;
  stages::deposit(classes, ps, *flow.field(), cp, deposits, at_walls, on_plates);
  EXPECT_EQ(at_walls, 1);
  EXPECT_EQ(on_plates, 1);
  EXPECT_NEAR(deposits.depositedVolume(), 2 * vol, 1e-12 * vol);
  // The plate deposit thinned its pixel (column 5, row 14 from the top) by
  // vol / (packing x pixel^2), at most one diameter.
  const auto ap = deposits.aperture();
  const double layer = std::min(vol / (0.365 * o.pixel * o.pixel), d);
  EXPECT_NEAR(ap[14 * 20 + 5], o.depth - layer, 1e-9 * o.depth);
  EXPECT_EQ(classes[0].accounted[0] & stages::kVolumeBooked, stages::kVolumeBooked);
  EXPECT_EQ(classes[0].accounted[2], 0);
  // The same frame again: nothing new.
  stages::deposit(classes, ps, *flow.field(), cp, deposits, at_walls, on_plates);
  EXPECT_EQ(at_walls + on_plates, 2);
  EXPECT_NEAR(deposits.depositedVolume(), 2 * vol, 1e-12 * vol);
  // Column mode: a plate deposit fills columns too and leaves every aperture at the depth.
  DepositGrid columns(grains, o.pixel, o.depth, 0.5, DepositLayerModel{0.365, d});
  cp.layers = false;
  classes[0].accounted.assign(3, 0);
  stages::deposit(classes, ps, *flow.field(), cp, columns, at_walls, on_plates);
  for (double a : columns.aperture()) EXPECT_TRUE(a == o.depth || a == 0.0);
  EXPECT_NEAR(columns.depositedVolume(), 2 * vol, 1e-12 * vol);
}

TEST(MicromodelStages, ResolveWaitsForItsThresholdThenSeesTheDeposits) {
  // An open 20 x 10 px slot (10 um px, 20 um deep, slip sides, as in
  // FlowThroughThinnedAperturesFollowsTheReynoldsEquation). Layers 10 um thick on
  // the downstream half halve its aperture: resistances in series, k / k0 =
  // 1 / (0.5 + 0.5 x 2^3) exactly (Reynolds equation). Each such pixel loses half
  // a column; the threshold is 40 columns, so 79 pixels (39.5) do not re-solve and
  // 100 (50) do. Then a wall of closed pixels across the slot: half of it captures
  // the particle standing there, all of it leaves no flow path and the pump stalls.
  const PixelMask open = PixelMask::Constant(10, 20, false);
  MicromodelFlowOptions o;
  o.pixel = 10e-6;
  o.depth = 20e-6;
  o.darcy_velocity = 1e-4;
  MicromodelFlow flow(open, o);
  const FlowSolveResult r0 = flow.solve({});
  const DepositLayerModel lm{0.365, 5e-6};
  DepositGrid deposits(open, o.pixel, o.depth, 0.5, lm);
  stages::Coupling cp;
  cp.layers = true;
  cp.resolve_pixels = 40;
  std::vector<stages::SizeClass> classes(1);
  classes[0].diameter = 5e-6;
  stages::makeEngines(classes, flow.field(), stageScene(5e-6, 1), 1);
  classes[0].engine->insert({Vec3(55e-6, 75e-6, 10e-6)});  // in pixel (column 5, row 2)
  stages::ClassParticles ps{classes[0].engine->particles()};
  std::int64_t resolves = 0, kept = 0;
  double seconds = 0, lost = 0, k = r0.permeability, pressure_drop = 0, blocked_at = -1;
  const auto record = [&] { return stages::FlowRecord{resolves, kept, seconds, lost, k, pressure_drop, blocked_at}; };
  const double per_pixel = lm.packing * o.pixel * o.pixel * 10e-6;  // a 10 um layer on one pixel
  int n = 0;
  for (int c = 10; c < 20; ++c)
    for (int r = 0; r < 10; ++r, ++n) {
      if (n == 79) {
        EXPECT_FALSE(stages::resolve(flow, deposits, cp, 0, 1.0, classes, ps, record()).has_value());
        EXPECT_EQ(resolves, 0);
        EXPECT_EQ(k, r0.permeability);
      }
      deposits.addLayer((c + 0.5) * o.pixel, (9 - r + 0.5) * o.pixel, per_pixel, 10e-6);
    }
  EXPECT_FALSE(stages::resolve(flow, deposits, cp, 0, 2.0, classes, ps, record()).has_value());
  EXPECT_EQ(resolves, 1);
  EXPECT_NEAR(lost, 50.0, 1e-9);
  EXPECT_NEAR(k / r0.permeability, 1.0 / 4.5, 1e-9);
  EXPECT_EQ(blocked_at, -1);
  // Column 5, rows 0-4 closed (one column capacity each): the particle in row 2 is captured.
  cp.resolve_pixels = 5;
  for (int r = 0; r < 5; ++r) deposits.add(5.5 * o.pixel, (9 - r + 0.5) * o.pixel, deposits.capacity());
  EXPECT_FALSE(stages::resolve(flow, deposits, cp, 0, 3.0, classes, ps, record()).has_value());
  EXPECT_EQ(resolves, 2);
  EXPECT_EQ(ps[0][0].status, ParticleStatus::deposited);
  EXPECT_GT(k, 0.0);
  // Rows 5-9 too: no path left; the pump stalls at t = 4 s with no pressure that could drive it.
  for (int r = 5; r < 10; ++r) deposits.add(5.5 * o.pixel, (9 - r + 0.5) * o.pixel, deposits.capacity());
  const auto stall = stages::resolve(flow, deposits, cp, 0, 4.0, classes, ps, record());
  ASSERT_TRUE(stall.has_value());
  EXPECT_EQ(stall->reason, PumpStall::Reason::no_flow_path);
  EXPECT_EQ(stall->time_s, 4.0);
  EXPECT_EQ(blocked_at, 4.0);
  EXPECT_EQ(k, 0.0);
  EXPECT_EQ(resolves, 3);
}

TEST(MicromodelStages, RecordFrameWritesADepositOnceAndMeasuresSpeedsBetweenFrames) {
  // Three particles of one class (ids 7, 8, 9): mobile, deposited, left. The
  // mobile one moved (3, 4) um since the last frame 0.1 s ago: 50 um/s. Rows are
  // image pixels from the top-left pixel's centre: x_px = X/p - 1/2, y_px = (H - Y)/p - 1/2.
  std::vector<stages::SizeClass> classes(1);
  classes[0].global_id = {7, 8, 9};
  classes[0].accounted.assign(3, 0);
  stages::ClassParticles ps(1, std::vector<ParticleState>(3));
  ps[0][0].x = Vec3(53e-6, 24e-6, 3e-6);
  ps[0][1].x = Vec3(80e-6, 40e-6, 2.5e-6);
  ps[0][1].status = ParticleStatus::deposited;
  ps[0][2].x = Vec3(210e-6, 50e-6, 5e-6);
  ps[0][2].status = ParticleStatus::left;
  stages::RunnerState s;
  s.k = s.k0 = 2e-12;
  s.last = {{7, 50e-6, 20e-6}};
  const stages::ImageFrame image{10e-6, 100e-6};
  const Counts n = stages::recordFrame(classes, ps, 4, 0.4, image, 0.1, s);
  EXPECT_EQ(n.injected, 3);
  EXPECT_EQ(n.inside + n.deposited + n.left, 3);
  ASSERT_EQ(s.rows.size(), 2u);
  EXPECT_EQ(s.rows[0].particle, 7);
  EXPECT_NEAR(s.rows[0].x_px, 4.8, 1e-12);
  EXPECT_NEAR(s.rows[0].y_px, 7.1, 1e-12);
  EXPECT_EQ(s.rows[1].particle, 8);
  EXPECT_EQ(s.rows[1].deposited, 1);
  EXPECT_NEAR(s.speed_sum, 50e-6, 1e-15);
  EXPECT_EQ(s.speed_n, 1);
  EXPECT_EQ(s.next_frame, 5);
  // frame, t_s, injected, inside, retained, left, retained_fraction (docs/outputs.md, "Tables")
  EXPECT_EQ(s.retention, "4,0.4,3,1,1,1,0.333333333\n");
  EXPECT_NE(s.permeability.find("0.4,2e-12,"), std::string::npos) << s.permeability;
  // The next frame: the deposit is not written again; the mobile one moved 10 um in x.
  ps[0][0].x = Vec3(63e-6, 24e-6, 3e-6);
  stages::recordFrame(classes, ps, 5, 0.5, image, 0.1, s);
  ASSERT_EQ(s.rows.size(), 3u);
  EXPECT_EQ(s.rows[2].particle, 7);
  EXPECT_NEAR(s.speed_sum, 50e-6 + 100e-6, 1e-15);
  EXPECT_EQ(s.speed_n, 2);
}

}  // namespace
}  // namespace mmval::particles
