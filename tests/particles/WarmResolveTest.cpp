// Warm re-solves of the micromodel scene (MicromodelFlowOptions::warm_start, SolverOptions::
// keep_factorisation): after deposits close pixels and plate layers thin the aperture, the
// kept solver must give what a fresh direct solve of the same geometry gives. Reference: the
// direct solve (a new solver, LU of the current matrix), the path every re-solve took before.
// Default warm start (numeric refactorisation with the kept ordering and symbolic analysis while
// the pattern stays; the sharp solve's pattern changes with every closed pixel, and then a new
// matrix is ordered and analysed as a new solver does): the same bytes, which is what keeps
// checkpoint/resume exact. GMRES preconditioned by the kept factors (warm_max_iterations > 0)
// stops at a preconditioned residual of 1e-12 of the right-hand side; k then agrees to ~1e-11
// and the tests allow 1e-8 (k/k0 is written with 6 digits). The velocities agree less well
// where pixels closed: there the sharp rows changed from momentum stencils to identities
// (u = 0), which the kept factors do not know, so the preconditioned residual bounds their
// error more loosely (measured 2.8e-8 of the largest velocity after 33 iterations, 1e-9 to 5e-9
// elsewhere); the tests allow 1e-7, still 10 times below the 6 digits written. Unit tier: masks of 120 x 60 pixels, under a second each. The
// DISABLED_ benchmark replays a deposit sequence on the full Pore2Chip mask (minutes; run with
// --gtest_also_run_disabled_tests; MMVAL_BENCH_STEPS re-solves, MMVAL_BENCH_ITS GMRES budget,
// MMVAL_BENCH_CPP cells per pixel, MMVAL_BENCH_MASK another mask (grains dark) and MMVAL_BENCH_PIXEL_UM its
// pixel size, MMVAL_BENCH_LOSS the pore columns lost per step (fraction, 5e-3), MMVAL_BENCH_SAME_PATTERN aperture-only steps, MMVAL_BENCH_FIXED the
// clean chip's pattern kept (SolverOptions::fixed_pattern) by the warm solver, MMVAL_BENCH_WARM_ONLY
// no direct solves, MMVAL_BENCH_SAVE / MMVAL_BENCH_REF a file the warm re-solves' k and velocities
// are written to / compared with (another build's answers); measurements in
// docs/validation/particle-physics.md, "Cost of the fluid re-solves"). Grids of 40000 cells and more
// (the benchmark's Pore2Chip at 0.5 and 1 cell per pixel) are solved by the friction split instead
// (FGMRES, see MicromodelFlow.cpp kSplitCells), warm or not: the benchmark then times the split, and
// MMVAL_BENCH_REF compares it with a file saved by a build that solved them by the LU.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <memory>
#include <random>
#include <vector>

#include "GrainMask.hpp"
#include "mmval/particles/DepositGrid.hpp"
#include "mmval/particles/MicromodelFlow.hpp"
#include "mmval/simulate/FlowSolver.hpp"
#include "mmval/simulate/Geometry.hpp"
#include "mmval/simulate/Grid.hpp"
#include "mmval/simulate/PoreSpace.hpp"

namespace mmval::particles {
namespace {

constexpr double kPixel = 5e-6, kDepth = 20e-6;
constexpr double kAgree = 1e-8;         ///< warm against fresh direct: k, relative (see the header)
constexpr double kAgreeVelocity = 1e-7;  ///< warm against fresh direct: velocities over the largest (see the header)

PixelMask grains() { return test_support::roundGrains120x60(); }

// Not the kept pattern: it equals a new solver to rounding only (FixedPatternTest); these tests compare bits.
MicromodelFlowOptions options(bool warm) { return test_support::flowOptions(kPixel, kDepth, 0.5, warm, false); }

void depositSome(DepositGrid& d, const PixelMask& solid, std::mt19937& rng, int n) {
  test_support::depositSome(d, solid, rng, n, kPixel, kDepth);
}

/// The node arrays the engines see and k, byte for byte (the same code path, not a tolerance).
bool sameBits(const MicromodelFlow& a, const FlowSolveResult& ra, const MicromodelFlow& b, const FlowSolveResult& rb) {
  const auto same = [](const std::vector<double>& x, const std::vector<double>& y) {
    return x.size() == y.size() && std::memcmp(x.data(), y.data(), x.size() * sizeof(double)) == 0;
  };
  return same(a.nodeUx(), b.nodeUx()) && same(a.nodeUy(), b.nodeUy()) && std::memcmp(&ra.permeability, &rb.permeability, sizeof(double)) == 0;
}

using test_support::velocityDeviation;

TEST(WarmResolve, FirstSolveIsTheDirectSolveBitForBit) {
  MicromodelFlow warm(grains(), options(true)), direct(grains(), options(false));
  const FlowSolveResult a = warm.solve({}), b = direct.solve({});
  EXPECT_TRUE(a.factorised);
  EXPECT_EQ(a.iterations, 0);
  // Identity of the code path, not a tolerance: the same LU solve of the same matrix.
  ASSERT_EQ(warm.nodeUx().size(), direct.nodeUx().size());
  EXPECT_EQ(std::memcmp(warm.nodeUx().data(), direct.nodeUx().data(), warm.nodeUx().size() * sizeof(double)), 0);
  EXPECT_EQ(std::memcmp(&a.permeability, &b.permeability, sizeof(double)), 0) << a.permeability << " vs " << b.permeability;
}

TEST(WarmResolve, ReSolvesWithTheKeptAnalysisAreTheDirectSolvesBitForBit) {
  // The default warm start: every re-solve factorises, numerically with the kept ordering and
  // symbolic analysis while the pattern stays, as a new solver when closed pixels changed it.
  // Byte equality with a new solver per re-solve is what keeps a resumed run identical to an
  // uninterrupted one (the checkpoint carries no factors).
  const PixelMask solid = grains();
  MicromodelFlow warm(solid, options(true));
  warm.solve({});
  DepositGrid d(solid, kPixel, kDepth, 0.5);
  std::mt19937 rng(17);
  for (int step = 0; step < 3; ++step) {
    depositSome(d, solid, rng, 6);
    const FlowSolveResult w = warm.solve(d.closed(), d.aperture());
    MicromodelFlow fresh(solid, options(false));
    const FlowSolveResult f = fresh.solve(d.closed(), d.aperture());
    EXPECT_TRUE(w.factorised);
    EXPECT_EQ(w.iterations, 0);
    EXPECT_TRUE(sameBits(warm, w, fresh, f)) << "re-solve " << step << ": k " << w.permeability << " vs " << f.permeability;
  }
}

TEST(WarmResolve, GmresReSolvesEqualFreshDirectSolvesAsDepositsGrow) {
  const PixelMask solid = grains();
  MicromodelFlowOptions o = options(true);
  // Each re-solve closes pixels: 60, 86, 106 and over 120 GMRES iterations with the sharp solve and
  // closed pixels as closed squares (33 to 73 when a closed pixel's far edge stayed fluid; the
  // penalized solve needed under 40), so a budget of 140 keeps the kept factors for at least three of four,
  // with a margin for rounding differences between BLAS builds.
  o.warm_max_iterations = 140;
  MicromodelFlow warm(solid, o);
  warm.solve({});
  DepositGrid d(solid, kPixel, kDepth, 0.5);
  std::mt19937 rng(11);
  int warm_solves = 0;
  for (int step = 0; step < 4; ++step) {
    depositSome(d, solid, rng, 6);
    const FlowSolveResult w = warm.solve(d.closed(), d.aperture());
    MicromodelFlow fresh(solid, options(false));
    const FlowSolveResult f = fresh.solve(d.closed(), d.aperture());
    ASSERT_FALSE(f.blocked);
    warm_solves += w.factorised ? 0 : 1;
    EXPECT_NEAR(w.permeability, f.permeability, kAgree * f.permeability) << "re-solve " << step;
    EXPECT_NEAR(w.pressure_drop, f.pressure_drop, kAgree * f.pressure_drop) << "re-solve " << step;
    const double dev = velocityDeviation(warm, fresh);
    EXPECT_LT(dev, kAgreeVelocity) << "re-solve " << step;
    std::printf("re-solve %d: k %.12g (fresh %.12g), %d GMRES iterations, %s, velocity deviation %.2g\n", step, w.permeability,
                f.permeability, w.iterations, w.factorised ? "factorised" : "kept factors", dev);
  }
  // The point of the feature: the small changes are solved with the kept factors.
  EXPECT_GE(warm_solves, 3);
}

TEST(WarmResolve, FactorisesWhenGmresRunsOutOfIterations) {
  const PixelMask solid = grains();
  MicromodelFlowOptions o = options(true);
  o.warm_max_iterations = 1;  // no change converges in one iteration: every re-solve factorises
  MicromodelFlow warm(solid, o), fresh(solid, options(false));
  warm.solve({});
  DepositGrid d(solid, kPixel, kDepth, 0.5);
  std::mt19937 rng(5);
  depositSome(d, solid, rng, 6);
  const FlowSolveResult w = warm.solve(d.closed(), d.aperture()), f = fresh.solve(d.closed(), d.aperture());
  EXPECT_TRUE(w.factorised);
  EXPECT_EQ(w.iterations, 1);
  // Then the plain LU solve of the current matrix, as a new solver's.
  EXPECT_TRUE(sameBits(warm, w, fresh, f)) << "k " << w.permeability << " vs " << f.permeability;
}

TEST(WarmResolve, UpdateRejectsAnotherGrid) {
  simulate::FlowProblem p;
  p.x = simulate::uniformAxis(0, 1e-3, 8);
  p.y = simulate::uniformAxis(0, 1e-3, 8);
  simulate::SteadyFlowSolver s(p);
  simulate::FlowProblem q = p;
  q.x = simulate::uniformAxis(0, 1e-3, 9);
  EXPECT_THROW(s.update(q), std::invalid_argument);
  q = p;
  q.boundary[0].type = simulate::BoundaryType::slip;
  EXPECT_THROW(s.update(q), std::invalid_argument);
}

/// A 40 x 20 cell depth-averaged channel (5 um cells) driven by 1 Pa from west to east, around `circles`.
simulate::FlowProblem channelAround(std::vector<simulate::Circle> circles) {
  simulate::FlowProblem p = test_support::pressureDrivenChannel40x20(kPixel, kDepth);
  if (!circles.empty()) p.shape = std::make_shared<simulate::Circles>(std::move(circles));
  return p;
}

TEST(WarmResolve, FixedPatternFallsBackToANewSolverWhenRowsDoNotFitAndKeepsItsOwn) {
  // The kept pattern is the empty channel's; cylinders cut stencils and merge the cells whose
  // centres they cover into neighbours, entries the empty channel's rows may not hold, so the
  // re-solve must be a new solver's (found while assembling: CoupledSystem throws PatternMiss
  // before it changes anything). Reference: a solver built for the cylinder alone, the same
  // path (own pattern, new ordering): the same bytes. Then the empty channel again fits, and is
  // solved by the kept solver (its LU of the kept pattern, not the parked one's): the first
  // solve's bytes, since the same matrix is factorised numerically in the same analysis.
  simulate::SolverOptions so;
  so.keep_factorisation = true;
  so.fixed_pattern = true;
  simulate::SteadyFlowSolver fixed(channelAround({}), so);
  EXPECT_FALSE(fixed.solve().pattern_kept);
  const Eigen::ArrayXXd u0 = fixed.u();
  const double q0 = fixed.flowRate(simulate::Side::east);
  // A large cylinder, and a small one that covers the centre of cell (28, 10) and its east and north
  // face nodes but not its west and south ones: the cell merges into a neighbour across one of
  // them, and the other's momentum row then holds that neighbour's pressure, beyond the stencil.
  const std::vector<simulate::Circle> cylinder{{12 * kPixel, 10 * kPixel, 4.3 * kPixel}, {28.6 * kPixel, 10.6 * kPixel, 0.56 * kPixel}};
  fixed.update(channelAround(cylinder));
  const simulate::FlowStats& st = fixed.solve();
  EXPECT_FALSE(st.pattern_kept);
  EXPECT_EQ(st.factorisations, 1);
  simulate::SteadyFlowSolver alone(channelAround(cylinder));
  alone.solve();
  const double q = fixed.flowRate(simulate::Side::east);
  EXPECT_LT(q, 0.99 * q0);  // the cylinder blocks 43 % of the width
  EXPECT_EQ(q, alone.flowRate(simulate::Side::east));
  EXPECT_TRUE((fixed.u() == alone.u()).all() && (fixed.v() == alone.v()).all());
  fixed.update(channelAround({}));
  EXPECT_TRUE(fixed.solve().pattern_kept);
  EXPECT_EQ(fixed.flowRate(simulate::Side::east), q0);
  EXPECT_TRUE((fixed.u() == u0).all());
}

/// Benchmark (opt-in): the full Pore2Chip mask at the full scene's former settings (10 um/px, 20 um
/// deep, 0.5 cells per pixel unless MMVAL_BENCH_CPP), deposits of 5 um parcels added until 0.5 % of the
/// pore columns are lost (the full case's resolve_threshold until 2026-12-05), then a warm and a direct re-solve
/// (MMVAL_BENCH_SAME_PATTERN: a uniformly thinner aperture instead, which keeps the matrix pattern).
TEST(WarmResolve, DISABLED_BenchmarkPore2Chip) {
  const char* mask = std::getenv("MMVAL_BENCH_MASK");
  const PixelMask solid =
      simulate::analysePoreSpace(simulate::readMask(mask ? std::string(mask) : std::string(MMVAL_SHARED_DATA_DIR) + "/pore2chip/grain_network.png", true))
          .solid_connected;
  MicromodelFlowOptions o = options(true);
  o.warm_max_iterations = std::getenv("MMVAL_BENCH_ITS") ? std::atoi(std::getenv("MMVAL_BENCH_ITS")) : 0;
  o.pixel = std::getenv("MMVAL_BENCH_PIXEL_UM") ? 1e-6 * std::atof(std::getenv("MMVAL_BENCH_PIXEL_UM")) : 10e-6;
  o.darcy_velocity = 4.17e-4;
  if (const char* cpp = std::getenv("MMVAL_BENCH_CPP")) o.cells_per_pixel = std::atof(cpp);
  o.fixed_pattern = std::getenv("MMVAL_BENCH_FIXED") != nullptr;  // the clean chip's pattern kept (numeric LU only while it fits)
  MicromodelFlowOptions od = o;
  od.warm_start = false;
  MicromodelFlow warm(solid, o), direct(solid, od);
  std::printf("first solve %.2f s\n", warm.solve({}).seconds);
  DepositGrid d(solid, o.pixel, kDepth, 0.5);
  std::mt19937 rng(3);
  const double pore = static_cast<double>((solid == false).count()), parcel = 241 * M_PI / 6 * 125e-18;
  std::uniform_int_distribution<int> col(2, static_cast<int>(solid.cols()) - 3), row(0, static_cast<int>(solid.rows()) - 1);
  double warm_s = 0, direct_s = 0;
  const bool warm_only = std::getenv("MMVAL_BENCH_WARM_ONLY") != nullptr;
  // Another build's answers: per re-solve k, then the node velocities (raw doubles, this machine's layout).
  std::ofstream save;
  std::ifstream ref;
  if (const char* path = std::getenv("MMVAL_BENCH_SAVE")) save.open(path, std::ios::binary);
  if (const char* path = std::getenv("MMVAL_BENCH_REF")) ref.open(path, std::ios::binary);
  for (int step = 0; step < (std::getenv("MMVAL_BENCH_STEPS") ? std::atoi(std::getenv("MMVAL_BENCH_STEPS")) : 12); ++step) {
    const double target = d.lostColumns() + (std::getenv("MMVAL_BENCH_LOSS") ? std::atof(std::getenv("MMVAL_BENCH_LOSS")) : 5e-3) * pore;
    for (int n = 0; d.lostColumns() < target; ++n) {
      const int c = col(rng), r = row(rng);
      if (solid(r, c) || d.closed()(r, c)) continue;
      const double x = (c + 0.5) * o.pixel, y = (solid.rows() - 1 - r + 0.5) * o.pixel;
      if (n % 3 == 0) d.add(x, y, parcel);
      else d.addLayer(x, y, parcel, 5e-6);
    }
    // MMVAL_BENCH_SAME_PATTERN: a uniform 1 % thinner aperture instead (the matrix keeps its pattern).
    const bool same_pattern = std::getenv("MMVAL_BENCH_SAME_PATTERN") != nullptr;
    const std::vector<double> thinner(static_cast<std::size_t>(solid.size()), (1 - 0.01 * (step + 1)) * kDepth);
    const std::clock_t c0 = std::clock();
    const FlowSolveResult w = same_pattern ? warm.solve({}, thinner) : warm.solve(d.closed(), d.aperture());
    const std::clock_t c1 = std::clock();
    if (save.is_open()) {
      save.write(reinterpret_cast<const char*>(&w.permeability), sizeof(double));
      save.write(reinterpret_cast<const char*>(warm.nodeUx().data()), static_cast<std::streamsize>(warm.nodeUx().size() * sizeof(double)));
      save.write(reinterpret_cast<const char*>(warm.nodeUy().data()), static_cast<std::streamsize>(warm.nodeUy().size() * sizeof(double)));
    }
    if (ref.is_open()) {
      double k_ref = 0;
      std::vector<double> ux(warm.nodeUx().size()), uy(warm.nodeUy().size());
      ref.read(reinterpret_cast<char*>(&k_ref), sizeof(double));
      ref.read(reinterpret_cast<char*>(ux.data()), static_cast<std::streamsize>(ux.size() * sizeof(double)));
      ref.read(reinterpret_cast<char*>(uy.data()), static_cast<std::streamsize>(uy.size() * sizeof(double)));
      ASSERT_TRUE(ref.good()) << "the reference file has fewer re-solves or other sizes";
      double dmax = 0, umax = 0;
      for (std::size_t k = 0; k < ux.size(); ++k) {
        dmax = std::max({dmax, std::abs(warm.nodeUx()[k] - ux[k]), std::abs(warm.nodeUy()[k] - uy[k])});
        umax = std::max({umax, std::abs(ux[k]), std::abs(uy[k])});
      }
      std::printf("re-solve %2d against the reference: k/k_ref - 1 = %.2g, velocity deviation %.2g\n", step, w.permeability / k_ref - 1, dmax / umax);
    }
    if (warm_only) {
      std::printf("re-solve %2d: warm %.2f s wall, %.2f s CPU (process, BLAS threads included), %s%s\n", step, w.seconds,
                  static_cast<double>(c1 - c0) / CLOCKS_PER_SEC, w.factorised ? "factorised" : "kept", w.pattern_kept ? ", kept pattern" : "");
      warm_s += w.seconds;
      continue;
    }
    const FlowSolveResult f = same_pattern ? direct.solve({}, thinner) : direct.solve(d.closed(), d.aperture());
    const std::clock_t c2 = std::clock();
    std::printf("re-solve %2d CPU (process, BLAS threads included): warm %.2f s, direct %.2f s\n", step,
                static_cast<double>(c1 - c0) / CLOCKS_PER_SEC, static_cast<double>(c2 - c1) / CLOCKS_PER_SEC);
    warm_s += w.seconds;
    direct_s += f.seconds;
    std::printf("re-solve %2d: warm %.2f s (%d its, %s%s), direct %.2f s, k/k_direct - 1 = %.2g, velocity deviation %.2g\n", step, w.seconds,
                w.iterations, w.factorised ? "factorised" : "kept", w.pattern_kept ? ", kept pattern" : "", f.seconds,
                w.permeability / f.permeability - 1, velocityDeviation(warm, direct));
    EXPECT_NEAR(w.permeability, f.permeability, kAgree * f.permeability);
    if (o.warm_max_iterations == 0 && !o.fixed_pattern) {
      EXPECT_TRUE(sameBits(warm, w, direct, f));
    }
  }
  std::printf("total: warm %.1f s, direct %.1f s\n", warm_s, direct_s);
}

}  // namespace
}  // namespace mmval::particles
