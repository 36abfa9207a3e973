// Chip-image permeability with its error bar: the grid-convergence arithmetic
// (observed order, Richardson extrapolation, GCI; Celik et al. 2008, J. Fluids Eng. 130 078001),
// the sub-pixel grain boundary reconstructed from a mask (SmoothMaskShape), and the
// image-permeability ladder (numerics.cells_per_pixel_levels) against Sangani & Acrivos (1982) on
// a square array of discs rendered as an image, plus two disc packings with narrow throats that
// the test renders itself. 1 MPI rank; the solver runs are kept to small masks (seconds).
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "mmval/core/Error.hpp"
#include "mmval/core/ReferenceData.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/simulate/Geometry.hpp"
#include "mmval/simulate/FlowSolver.hpp"
#include "mmval/simulate/GridConvergence.hpp"
#include "mmval/simulate/Kinds.hpp"
#include "mmval/simulate/PoreSpace.hpp"

#include "../TestScratch.hpp"

namespace fs = std::filesystem;
using namespace mmval;
using namespace mmval::simulate;

namespace {

const CaseKindRegistry& registry() {
  static const CaseKindRegistry r = [] {
    CaseKindRegistry reg;
    registerFluidKinds(reg);
    return reg;
  }();
  return r;
}

struct Disc {
  double x, y, r;  ///< pixels, x from the left edge, y from the top edge
};

/// A grain wherever a pixel's centre lies inside a disc.
BoolArray render(int rows, int cols, const std::vector<Disc>& discs) {
  BoolArray s = BoolArray::Constant(rows, cols, false);
  for (int i = 0; i < rows; ++i)
    for (int j = 0; j < cols; ++j)
      for (const auto& d : discs) {
        const double dx = j + 0.5 - d.x, dy = i + 0.5 - d.y;
        if (dx * dx + dy * dy < d.r * d.r) s(i, j) = true;
      }
  return s;
}

/// Grains black, pores white, as an 8-bit PGM.
fs::path writeMask(const BoolArray& s, const std::string& name) {
  const fs::path p = mmval::test::scratch(name);
  std::ofstream f(p, std::ios::binary);
  f << "P5\n" << s.cols() << " " << s.rows() << "\n255\n";
  for (int i = 0; i < s.rows(); ++i)
    for (int j = 0; j < s.cols(); ++j) f.put(static_cast<char>(s(i, j) ? 0 : 255));
  return p;
}

/// A row of `n` unit cells of side `cell` px, one disc of solid fraction phi centred in each: the
/// cells' edges are mirror planes of the periodic array's Stokes flow (u even, v and the periodic
/// part of p odd about them), so pressure inlet/outlet on the left and right edges and slip top
/// and bottom give the periodic array's permeability.
BoolArray squareArray(int n, int cell, double phi) {
  std::vector<Disc> discs;
  const double r = cell * std::sqrt(phi / M_PI);
  for (int k = 0; k < n; ++k) discs.push_back({(k + 0.5) * cell, 0.5 * cell, r});
  return render(cell, n * cell, discs);
}

/// Deterministic jitter in [-1, 1) (a 64-bit LCG, Knuth's MMIX constants).
struct Jitter {
  std::uint64_t state;
  double next() {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(state >> 11) / 4503599627370496.0 - 1.0;
  }
};

/// Near-touching grains on a jittered square lattice (spacing 16 px, radii 6.3-6.7 px, centres
/// moved up to 0.7 px): gaps of 2-4 px between neighbours. Pixels, y from the top.
std::vector<Disc> squarePacking(int rows, int cols) {
  Jitter j{25};
  std::vector<Disc> d;
  for (double y = 8; y < rows; y += 16)
    for (double x = 8; x < cols; x += 16) d.push_back({x + 0.7 * j.next(), y + 0.7 * j.next(), 6.5 + 0.2 * j.next()});
  return d;
}

/// Near-touching grains on a jittered hexagonal lattice (spacing 14 px, radii 5.3-5.7 px): gaps of
/// 1-3 px, throats at 60 degrees to the pixel rows.
std::vector<Disc> hexPacking(int rows, int cols) {
  Jitter j{2025};
  std::vector<Disc> d;
  const double a = 14, dy = a * std::sqrt(3.0) / 2;
  int row = 0;
  for (double y = 6; y < rows + a; y += dy, ++row)
    for (double x = (row % 2 == 0 ? 4 : 4 + a / 2); x < cols + a; x += a) d.push_back({x + 0.5 * j.next(), y + 0.5 * j.next(), 5.5 + 0.2 * j.next()});
  return d;
}

/// 2D permeability of the discs themselves (Circles, the sharp immersed boundary on the exact
/// circles) in the image-permeability set-up (pressure left to right, slip sides), at n cells per pixel.
double discPermeability(const std::vector<Disc>& discs, int rows, int cols, double pixel_m, double n) {
  std::vector<Circle> circles;
  for (const auto& d : discs) circles.push_back({d.x * pixel_m, (rows - d.y) * pixel_m, d.r * pixel_m});
  FlowProblem p;
  p.x = uniformAxis(0, cols * pixel_m, static_cast<int>(std::lround(cols * n)));
  p.y = uniformAxis(0, rows * pixel_m, static_cast<int>(std::lround(rows * n)));
  p.boundary[0].type = p.boundary[1].type = BoundaryType::pressure;
  p.boundary[0].pressure = 1.0;
  p.boundary[2].type = p.boundary[3].type = BoundaryType::slip;
  p.viscosity = 1e-3;
  p.shape = std::make_shared<Circles>(circles);
  SteadyFlowSolver s(p, SolverOptions{});
  s.solve();
  return 1e-3 * s.flowRate(Side::east) * cols / rows;  // k = mu Q L / (A dp), dp = 1 Pa
}

Case ladderCase(const fs::path& mask, const std::string& boundary, const std::string& levels, const std::string& extra = "") {
  const std::string text = "[case]\nname = \"ladder\"\nkind = \"image-permeability\"\n[geometry]\nmask = \"" + mask.string() +
                           "\"\npixel_size = \"10 um\"\nboundary = \"" + boundary + "\"\n[numerics]\ndepth_model = \"2d\"\ncells_per_pixel_levels = " +
                           levels + "\n" + extra;
  return Case::parse(text, mmval::test::scratch("ladder.toml"), registry());
}

RunOutput run(const Case& c) { return registry().find(c.kind())->run(c, RunContext{{}, true, false, 0}); }

double metric(const RunOutput& out, const std::string& name) {
  const auto it = out.metrics.find(name);
  if (it == out.metrics.end()) throw std::runtime_error("no metric " + name);
  return it->second;
}

}  // namespace

// ---- grid convergence arithmetic (no solve) --------------------------------

TEST(GridConvergence, PowerLawGivesItsOrderAndLimit) {
  // f = 3 + 0.7 h^p exactly: the observed order is p and the extrapolation the limit, to round-off,
  // for uniform and for non-uniform refinement ratios (Celik's fixed point is exact for a power law).
  for (const double p : {1.0, 2.0, 1.6}) {
    for (const std::vector<double>& h : {std::vector<double>{2, 1, 0.5}, std::vector<double>{2.7, 1.5, 1.0}, std::vector<double>{4, 2, 1, 0.5}}) {
      std::vector<double> f;
      for (const double x : h) f.push_back(3 + 0.7 * std::pow(x, p));
      const GridConvergence g = gridConvergence(h, f, 2);
      ASSERT_TRUE(g.has_order) << g.note;
      const std::size_t n = h.size();
      if (n >= 4) {  // four levels: the least-squares fit beside the three finest (exact here)
        ASSERT_TRUE(g.has_fit);
        EXPECT_NEAR(g.fit_order, p, 1e-6);
        EXPECT_NEAR(g.fit_extrapolated, 3, 1e-7);
        EXPECT_NEAR(g.fit_scatter, 0, 1e-7);
        // Fs |f1 - f0| + scatter + |f1 - fit(h1)|, Fs 1.25 for p in [0.5, 2.1] (else the p = 2 fit's, Fs 3).
        if (p <= 2.1) {
          EXPECT_NEAR(g.fit_uncertainty, 1.25 * std::abs(f[n - 1] - 3) / f[n - 1], 1e-6);
        }
      }
      EXPECT_EQ(g.status, "monotone");
      EXPECT_NEAR(g.observed_order, p, 1e-9);
      EXPECT_NEAR(g.extrapolated, 3, 1e-9);
      // Roache's GCI with Fs = 1.25 on the two finest levels.
      const double r = h[n - 2] / h[n - 1];
      EXPECT_NEAR(g.gci, 1.25 * std::abs((f[n - 1] - f[n - 2]) / f[n - 1]) / (std::pow(r, p) - 1), 1e-12);
      EXPECT_DOUBLE_EQ(g.safety_factor, 1.25);
      // The band holds the limit: Fs > 1 and an exact power law.
      EXPECT_LE(g.band_lo, 3.0);
      EXPECT_GE(g.band_hi, 3.0);
    }
  }
}

TEST(GridConvergence, NonMonotoneLaddersHaveNoOrder) {
  const GridConvergence osc = gridConvergence({2, 1, 0.5}, {10.0, 9.0, 9.4}, 2);
  EXPECT_FALSE(osc.has_order);
  EXPECT_EQ(osc.status, "oscillatory");
  EXPECT_TRUE(std::isnan(osc.extrapolated));
  EXPECT_DOUBLE_EQ(osc.safety_factor, 3.0);
  EXPECT_NEAR(osc.gci, 3 * 0.4 / 9.4 / 3.0, 1e-12);  // Fs 3, formal order 2, r = 2
  // The change grows on refinement: not in the asymptotic range.
  const GridConvergence div = gridConvergence({2, 1, 0.5}, {10.0, 9.9, 9.5}, 1);
  EXPECT_FALSE(div.has_order);
  EXPECT_EQ(div.status, "diverging");
  EXPECT_NE(div.note.find("grows"), std::string::npos) << div.note;
}

TEST(GridConvergence, LeastSquaresOverManyLevelsSeesTheOrderThroughScatter) {
  // f = 100 + 10 h^2 with +-0.05 alternating on six levels (1 to 4 cells per unit, as the Pore2Chip
  // ladder): the three finest alone give no order (the change grows through the scatter), the fit over all six finds 2.01 and the limit
  // to 0.002 (both computed independently by a brute-force scan), scatter ~0.065, and its band holds 100.
  const std::vector<double> h = {1, 2.0 / 3, 0.5, 0.4, 1.0 / 3, 0.25};
  std::vector<double> f;
  for (std::size_t i = 0; i < h.size(); ++i) f.push_back(100 + 10 * h[i] * h[i] + (i % 2 == 0 ? 0.05 : -0.05));
  const GridConvergence g = gridConvergence(h, f, 2);
  ASSERT_TRUE(g.has_fit) << g.note;
  EXPECT_EQ(g.fit_levels, 6);
  EXPECT_EQ(g.status, "least squares");
  EXPECT_NE(g.note.find("diverging") == std::string::npos ? g.note.find("grows") : 0, std::string::npos)
      << "the three finest levels (change growing on refinement through the scatter) give no order: " << g.note;
  EXPECT_DOUBLE_EQ(g.observed_order, g.fit_order);
  EXPECT_DOUBLE_EQ(g.extrapolated, g.fit_extrapolated);
  EXPECT_DOUBLE_EQ(g.gci, g.fit_uncertainty);
  EXPECT_NEAR(g.fit_order, 2.013, 0.01);
  EXPECT_NEAR(g.fit_extrapolated, 100.0015, 0.001);
  EXPECT_NEAR(g.fit_scatter, 0.0654, 0.001);
  EXPECT_DOUBLE_EQ(g.fit_order_used, g.fit_order);
  EXPECT_GE(g.fit_uncertainty * std::abs(g.fine), std::abs(g.fine - 100.0));
  EXPECT_NE(g.note.find("least squares over all 6 levels"), std::string::npos) << g.note;
  // A credible three-grid order keeps the three finest in charge: the same ladder with the scatter
  // gone from the finest three (so they see p = 2 exactly) reports their order, the fit beside it.
  std::vector<double> clean = f;
  for (std::size_t i = 3; i < h.size(); ++i) clean[i] = 100 + 10 * h[i] * h[i];
  const GridConvergence c = gridConvergence(h, clean, 2);
  EXPECT_EQ(c.status, "monotone");
  EXPECT_NEAR(c.observed_order, 2.0, 1e-6);
  EXPECT_TRUE(c.has_fit);
  // An exact power law: the fit is exact; three levels: no fit.
  std::vector<double> e;
  for (const double x : h) e.push_back(3 + 0.7 * std::pow(x, 1.6));
  const GridConvergence x = gridConvergence(h, e, 2);
  EXPECT_NEAR(x.fit_order, 1.6, 1e-6);
  EXPECT_NEAR(x.fit_extrapolated, 3.0, 1e-7);
  EXPECT_FALSE(gridConvergence({2, 1, 0.5}, {10.0, 9.0, 8.75}, 2).has_fit);
}

TEST(GridConvergence, TwoLevelsUseTheFormalOrderAndSafetyFactorThree) {
  const GridConvergence g = gridConvergence({1, 0.5}, {10.0, 9.0}, 2);
  EXPECT_EQ(g.status, "two levels");
  EXPECT_FALSE(g.has_order);
  EXPECT_NEAR(g.extrapolated, (4 * 9.0 - 10.0) / 3, 1e-12);
  EXPECT_NEAR(g.gci, 3 * (1.0 / 9.0) / 3, 1e-12);
  EXPECT_THROW(gridConvergence({1, 1}, {2, 3}, 2), std::invalid_argument);
  EXPECT_THROW(gridConvergence({1, 0.5}, {2}, 2), std::invalid_argument);
}

// ---- the sub-pixel boundary (no solve) -------------------------------------

TEST(SmoothMaskShape, PixelAlignedWallStaysOnThePixelEdge) {
  // Grains in the bottom 6 of 16 rows: the wall is the edge y = 6 px, for any smoothing width.
  BoolArray s = BoolArray::Constant(16, 20, false);
  s.bottomRows(6) = true;
  const double px = 1e-5;
  for (const double sigma : {0.0, 0.5, 1.0}) {
    const SmoothMaskShape shape(s, px, sigma);
    EXPECT_NEAR(shape.distanceAlong(7.3 * px, 9.0 * px, 1, -1, 4 * px), 3.0 * px, 1e-9 * px) << sigma;
    EXPECT_TRUE(shape.solid(7.3 * px, 5.99 * px));
    EXPECT_FALSE(shape.solid(7.3 * px, 6.01 * px));
  }
}

TEST(SmoothMaskShape, DiscBoundaryIsCloserThanTheStaircase) {
  // A disc of radius 12.3 px rendered by pixel centres. Along 720 rays from its centre, the
  // boundary's radius against 12.3: the staircase's corners stray up to ~0.7 px (rms ~0.3 px); the
  // smooth boundary (sigma 0.75 px) keeps rms ~0.19 px (the image cannot place the disc's extreme
  // points better than half a pixel), its mean radius within 0.06 px (Gaussian shrinkage of a
  // convex grain: sigma^2 / 2R = 0.023 px).
  const double R = 12.3, cx = 20.2, cy = 19.7;
  const BoolArray s = render(40, 40, {{cx, cy, R}});
  const SmoothMaskShape smooth(s, 1.0, 0.75);
  const MaskShape stairs(s, 1.0);
  auto radial = [&](const Shape& shape, double& mean, double& rms) {
    const int rays = 720;
    mean = rms = 0;
    for (int k = 0; k < rays; ++k) {
      const double a = 2 * M_PI * k / rays;
      double lo = 0, hi = R + 3;  // solid at lo, fluid at hi
      for (int it = 0; it < 50; ++it) {
        const double m = 0.5 * (lo + hi);
        (shape.solid(cx + m * std::cos(a), 40 - (cy + m * std::sin(a))) ? lo : hi) = m;
      }
      const double e = 0.5 * (lo + hi) - R;
      mean += e / rays;
      rms += e * e / rays;
    }
    rms = std::sqrt(rms);
  };
  double mean_smooth, rms_smooth, mean_stairs, rms_stairs;
  radial(smooth, mean_smooth, rms_smooth);
  radial(stairs, mean_stairs, rms_stairs);
  std::printf("disc R %.1f px: smooth boundary mean %+.3f rms %.3f px; staircase mean %+.3f rms %.3f px\n", R, mean_smooth, rms_smooth, mean_stairs,
              rms_stairs);
  // The smooth boundary's mean radius follows the pixels' (staircase mean) within the Gaussian's shrinkage (2 x sigma^2 / 2R).
  EXPECT_LT(std::abs(mean_smooth - mean_stairs), 0.75 * 0.75 / R);
  EXPECT_LT(std::abs(mean_smooth), 0.06);
  EXPECT_LT(rms_smooth, 0.2);
  EXPECT_GT(rms_stairs, 1.2 * rms_smooth);
}

TEST(SmoothMaskShape, OnePixelGapsGrainsAndWallsSurvive) {
  // A one-pixel wall pierced by a one-pixel slot, and a one-pixel grain: every pixel centre stays
  // on its side however wide the smoothing (blurred alone, sigma 1 px would remove the grain).
  BoolArray s = BoolArray::Constant(9, 9, false);
  s.col(4) = true;
  s(4, 4) = false;  // the slot
  s(1, 1) = true;   // the grain
  for (const double sigma : {0.5, 0.75, 1.0, 2.0}) {
    const SmoothMaskShape shape(s, 1.0, sigma);
    EXPECT_FALSE(shape.solid(4.5, 4.5)) << sigma;  // the slot
    EXPECT_TRUE(shape.solid(4.5, 2.5)) << sigma;   // the wall
    EXPECT_TRUE(shape.solid(1.5, 7.5)) << sigma;   // the grain
  }
  EXPECT_THROW(SmoothMaskShape(s, 1.0, -1), std::invalid_argument);
}

// ---- the image-permeability ladder ------------------------------------------

/// The two disc packings (48 x 48 px, 10 um pixels) rendered to pixels, through the kind's ladder
/// at 0.5, 1, 2, 4 cells per pixel on the smooth boundary, against the permeability of the discs
/// themselves (the same solver and boundaries on the exact circles, Richardson-extrapolated from 1, 2,
/// 4 cells per pixel). Checks: second order (>= 1.8) on the three finest levels; the GCI band of the
/// three coarsest levels holds the finest extrapolation (the error bar is honest); the extrapolated
/// image permeability within 5 % of the discs' (what the binary image loses: each throat wall placed
/// to ~0.2 px rms, the disc test above, in throats of 1-3 px; measured +2.7 % and +1.2 %).
void checkPacking(const std::vector<Disc>& discs, const std::string& name) {
  const int n = 48;
  const double px = 10e-6;
  std::vector<double> hd, kd;
  for (const double c : {1.0, 2.0, 4.0}) {
    hd.push_back(1 / c);
    kd.push_back(discPermeability(discs, n, n, px, c));
  }
  const GridConvergence truth = gridConvergence(hd, kd, 2);
  ASSERT_TRUE(truth.has_order) << truth.note;
  const fs::path mask = writeMask(render(n, n, discs), name + ".pgm");
  const RunOutput out = run(ladderCase(mask, "smooth", "[0.5, 1.0, 2.0, 4.0]"));
  const double p = metric(out, "permeability_2d_observed_order"), kx = metric(out, "permeability_2d_extrapolated");
  std::printf("%s: discs %.4g D (p %.2f); image, smooth boundary: extrapolated %.4g D (%+.2f %%), p %.2f, GCI %.3g %%\n", name.c_str(),
              truth.extrapolated / 9.869233e-13, truth.observed_order, kx / 9.869233e-13, 100 * (kx / truth.extrapolated - 1), p,
              100 * metric(out, "permeability_2d_gci"));
  EXPECT_GE(p, 1.8);
  EXPECT_LE(p, 3.5);
  EXPECT_NEAR(kx / truth.extrapolated, 1.0, 0.05);
  // The coarse three levels' error bar holds the fine three levels' extrapolation.
  const auto& rows = out.details.at("ladder");
  ASSERT_EQ(rows.size(), 4U);
  std::vector<double> h, k;
  for (int i = 0; i < 3; ++i) {
    h.push_back(1.0 / rows[static_cast<std::size_t>(i)].at("cells_per_pixel").get<double>());
    k.push_back(rows[static_cast<std::size_t>(i)].at("value").get<double>());
  }
  const GridConvergence coarse = gridConvergence(h, k, 2);
  EXPECT_LE(coarse.band_lo, kx);
  EXPECT_GE(coarse.band_hi, kx);
  EXPECT_EQ(out.details.at("grid_convergence").at("2d").at("status"), "monotone");
  // Four levels: the least-squares fit over all of them is reported beside (not used: the three finest are credible).
  const auto& ls = out.details.at("grid_convergence").at("2d").at("least_squares");
  EXPECT_EQ(ls.at("levels"), 4);
  EXPECT_NEAR(ls.at("permeability_extrapolated_D").get<double>() * 9.869233e-13 / truth.extrapolated, 1.0, 0.05);
}

TEST(ImageLadder, SquarePackingConvergesAtSecondOrderToItsDiscs) { checkPacking(squarePacking(48, 48), "square-packing"); }

TEST(ImageLadder, HexPackingConvergesAtSecondOrderToItsDiscs) { checkPacking(hexPacking(48, 48), "hex-packing"); }

TEST(ImageLadder, StaircaseConvergesAtFirstOrderBelowTheDiscs) {
  // The same hexagonal packing on the pixel staircase: the corners of the diagonal throats slow
  // convergence to about first order, and the staircase narrows the throats: the extrapolated
  // permeability lies far below the discs' (measured -41 %).
  const int n = 48;
  const auto discs = hexPacking(n, n);
  const double k_discs = discPermeability(discs, n, n, 10e-6, 4.0);  // within ~1 % of the discs' limit
  const RunOutput out = run(ladderCase(writeMask(render(n, n, discs), "hex-stairs.pgm"), "pixels", "[1.0, 2.0, 4.0]"));
  const double p = metric(out, "permeability_2d_observed_order");
  std::printf("hex packing, staircase: p %.2f, k %.4g D, discs %.4g D\n", p, metric(out, "permeability_2d") / 9.869233e-13, k_discs / 9.869233e-13);
  EXPECT_LT(p, 1.6);
  EXPECT_LT(metric(out, "permeability_2d"), 0.8 * k_discs);
}

TEST(ImageLadder, ThroatWarningNamesItsPixelAndWidth) {
  // The hexagonal packing's narrowest throat is 2.83 px (a diagonal run of 2 px); at 0.5 and 1 cells
  // per pixel it has fewer than 4 cells across: one warning per such level, naming the pixel
  // (column, row) and the width in px and cells.
  const RunOutput out = run(ladderCase(writeMask(render(48, 48, hexPacking(48, 48)), "hex-warn.pgm"), "pixels", "[0.5, 1.0]"));
  ASSERT_TRUE(out.details.contains("warnings"));
  int throat_warnings = 0;
  for (const auto& w : out.details["warnings"]) {
    const std::string t = w.get<std::string>();
    if (t.find("narrowest throat") == std::string::npos) continue;
    ++throat_warnings;
    EXPECT_NE(t.find("2.83 px"), std::string::npos) << t;
    EXPECT_NE(t.find("at pixel x = "), std::string::npos) << t;
    EXPECT_NE(t.find("numerics.cells_per_pixel_levels"), std::string::npos) << t;
  }
  EXPECT_EQ(throat_warnings, 2);
  EXPECT_NEAR(out.details.at("narrowest_throat").at("width_px").get<double>(), 2 * std::sqrt(2.0), 1e-9);
  // Two levels: no observed order, the two-grid GCI (Fs 3) with the staircase's formal order 1.
  EXPECT_EQ(out.details.at("grid_convergence").at("2d").at("status"), "two levels");
  EXPECT_FALSE(out.metrics.count("permeability_2d_observed_order"));
  EXPECT_TRUE(out.metrics.count("permeability_2d_gci"));
}

TEST(ImageLadder, LevelsMustGrow) {
  const fs::path mask = writeMask(squareArray(1, 16, 0.2), "disc-one.pgm");
  try {
    run(ladderCase(mask, "pixels", "[1.0, 0.5]"));
    FAIL() << "a falling ladder ran";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cells_per_pixel_levels"), std::string::npos) << e.what();
  }
}
