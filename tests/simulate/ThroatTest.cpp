// Throats: the narrowest cross-section of the widest inlet-to-outlet path
// (narrowestThroat) on masks and analytic shapes, and the resolution check the fluid kinds run
// before a solve (checkThroats): a throat narrower than one cell is a NumericalFailure naming the
// resolution key, narrower than two a warning. Unit tier: no solve, well under a second.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include <gtest/gtest.h>

#include "mmval/core/Error.hpp"
#include "mmval/simulate/PoreSpace.hpp"
#include "mmval/simulate/ThroatCheck.hpp"

using namespace mmval;
using namespace mmval::simulate;

namespace {

/// rows x cols of fluid with a solid wall across column `wall` pierced by a slot of `slot` pixels from row `row0`.
BoolArray wallWithSlot(int rows, int cols, int wall, int row0, int slot) {
  BoolArray s = BoolArray::Constant(rows, cols, false);
  for (int r = 0; r < rows; ++r) s(r, wall) = r < row0 || r >= row0 + slot;
  return s;
}

/// The image-permeability kind's problem for a mask: pressure-driven along x, slip sides.
FlowProblem maskProblem(const BoolArray& solid, double pixel, double cells_per_pixel) {
  const auto shape = std::make_shared<MaskShape>(solid, pixel);
  FlowProblem p;
  p.x = uniformAxis(0, shape->width(), std::max(4, static_cast<int>(std::lround(shape->cols() * cells_per_pixel))));
  p.y = uniformAxis(0, shape->height(), std::max(4, static_cast<int>(std::lround(shape->rows() * cells_per_pixel))));
  p.boundary[0].type = p.boundary[1].type = BoundaryType::pressure;
  p.boundary[2].type = p.boundary[3].type = BoundaryType::slip;
  p.shape = shape;
  return p;
}

}  // namespace

TEST(Throat, SlotWidthIsItsPixelCount) {
  // Exact for a slot across the flow: its fluid chord is the slot, to the pixel.
  const double px = 10e-6;
  for (int slot : {1, 2, 3, 5}) {
    const Throat t = narrowestThroat(wallWithSlot(12, 20, 9, 4, slot), px);
    ASSERT_TRUE(t.path) << slot;
    EXPECT_NEAR(t.width_m, slot * px, 1e-12 * px) << slot;
    EXPECT_NEAR(t.x_m, 9.5 * px, 1e-12 * px);  // in the wall's column
  }
}

TEST(Throat, OpenAndClosedMasks) {
  const BoolArray open = BoolArray::Constant(6, 9, false);
  const Throat t = narrowestThroat(open, 1e-6);
  EXPECT_TRUE(t.path);
  EXPECT_TRUE(std::isinf(t.width_m));  // the mask's edges are inlet, outlet and slip sides: nothing narrows the path
  BoolArray closed = wallWithSlot(6, 9, 4, 0, 0);
  EXPECT_FALSE(narrowestThroat(closed, 1e-6).path);
  // A channel of 3 pixels between solid rows (the top and bottom rows are grain).
  BoolArray channel = BoolArray::Constant(5, 9, false);
  channel.row(0).setConstant(true);
  channel.row(4).setConstant(true);
  EXPECT_NEAR(narrowestThroat(channel, 1e-6).width_m, 3e-6, 1e-18);
}

// A strip with mirror sides (no wall rows): a grain band leaves a gap of g pixels to the top edge.
// Without mirrors the gap is open (a slip side: no throat); with them it reaches the grain's mirror
// image, 2 g wide, unless another gap is narrower.
TEST(Throat, MirrorSidesDoubleTheGapToAnEdge) {
  const double px = 1e-6;
  for (const int g : {2, 3, 5}) {
    BoolArray s = BoolArray::Constant(20, 30, false);
    for (int r = g; r < 20; ++r) s(r, 12) = s(r, 13) = true;  // a wall across x from row g down to the bottom edge
    EXPECT_FALSE(std::isfinite(narrowestThroat(s, px).width_m)) << g;
    const Throat t = narrowestThroat(s, px, false, false, 0, 0, true);
    ASSERT_TRUE(t.path);
    EXPECT_NEAR(t.width_m, 2 * g * px, 1e-18) << g;
    EXPECT_LT(t.x_m, 14e-6);
    EXPECT_GT(t.x_m, 11e-6);
  }
  // A fluid column from edge to edge has no solid on either side: open even with mirrors.
  EXPECT_FALSE(std::isfinite(narrowestThroat(BoolArray::Constant(10, 10, false), px, false, false, 0, 0, true).width_m));
}

TEST(Throat, SquareArrayGapIsLMinusTwoRadii) {
  // Periodic square array, cell L: the flow passes between vertically neighbouring cylinders, gap
  // L - 2a. Sampled at 1/8 of a 32-cell grid's cell (L / 256): the width is known to one sample.
  const double L = 100e-6;
  for (double phi : {0.2, 0.5, 0.75}) {
    const FlowProblem p = squareArrayProblem(L, 32, phi, 1e-3, 1.0);
    const Throat t = narrowestThroat(*p.shape, 0, L, 0, L, L / 256, true, true);
    const double gap = L * (1 - 2 * std::sqrt(phi / M_PI));
    ASSERT_TRUE(t.path) << phi;
    EXPECT_NEAR(t.width_m, gap, L / 256 + 1e-15) << "phi " << phi;
  }
}

TEST(Throat, GapUnderOneCellIsANumericalFailureNamingTheKey) {
  // phi 0.75 at 32 cells: gap 0.0228 L = 0.73 cells. The failure names the resolution, not just "the fluid solution is not finite".
  const FlowProblem p = squareArrayProblem(100e-6, 32, 0.75, 1e-3, 1.0);
  RunOutput out;
  try {
    checkThroats(p, "numerics.cells_around", 32, out, true);
    FAIL() << "a gap of 0.73 cells passed";
  } catch (const NumericalFailure& e) {
    const std::string m = e.what();
    EXPECT_EQ(e.key(), "numerics.cells_around");
    EXPECT_NE(m.find("change 'numerics.cells_around'"), std::string::npos) << m;
    EXPECT_NE(m.find("narrower than one cell"), std::string::npos) << m;
    // 2 cells across a gap of 0.0228 L need L / h >= 88 (to one sample: 85..103).
    const auto at = m.find("at least ");
    ASSERT_NE(at, std::string::npos) << m;
    const int suggested = std::stoi(m.substr(at + 9));
    EXPECT_GE(suggested, 85) << m;
    EXPECT_LE(suggested, 103) << m;
  }
  // 96 cells: 2.19 cells across the gap, no warning.
  RunOutput fine;
  EXPECT_NEAR(checkThroats(squareArrayProblem(100e-6, 96, 0.75, 1e-3, 1.0), "numerics.cells_around", 96, fine, true), 2.19, 1.0 / 8 + 0.01);
  EXPECT_FALSE(fine.details.contains("warnings"));
}

TEST(Throat, OnePixelThroatFailsAtHalfACellPerPixelAndWarnsAtOne) {
  const BoolArray mask = wallWithSlot(20, 40, 19, 10, 1);
  RunOutput out;
  try {
    checkThroats(maskProblem(mask, 10e-6, 0.5), "numerics.cells_per_pixel", 0.5, out, true);
    FAIL() << "a one-pixel throat at 0.5 cells per pixel passed";
  } catch (const NumericalFailure& e) {
    EXPECT_EQ(e.key(), "numerics.cells_per_pixel");
    EXPECT_NE(std::string(e.what()).find("0.50 cells wide"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("at least 2.00"), std::string::npos) << e.what();
  }
  EXPECT_NEAR(checkThroats(maskProblem(mask, 10e-6, 1.0), "numerics.cells_per_pixel", 1.0, out, true), 1.0, 1e-12);
  ASSERT_TRUE(out.details.contains("warnings"));
  ASSERT_EQ(out.details["warnings"].size(), 1U);
  const std::string w = out.details["warnings"][0].get<std::string>();
  EXPECT_NE(w.find("1.00 cells wide"), std::string::npos) << w;
  EXPECT_NE(w.find("'numerics.cells_per_pixel' to at least 2"), std::string::npos) << w;
  // Two cells per pixel: resolved, no further warning.
  EXPECT_NEAR(checkThroats(maskProblem(mask, 10e-6, 2.0), "numerics.cells_per_pixel", 2.0, out, true), 2.0, 1e-12);
  EXPECT_EQ(out.details["warnings"].size(), 1U);
}

TEST(Throat, ShippedPore2ChipMaskPassesAtItsCellsPerPixel) {
  // The bundled image-permeability cases run the Pore2Chip mask at 0.5 cells per pixel: the check
  // must not refuse it (its widest path is narrowest at several pixels).
  const std::filesystem::path mask = std::filesystem::path(MMVAL_SOURCE_DIR) / "../shared/data/pore2chip/grain_network.png";
  if (!std::filesystem::exists(mask)) GTEST_SKIP() << "no " << mask;
  const PoreSpaceReport pores = analysePoreSpace(readMask(mask, true));
  const Throat t = narrowestThroat(pores.solid_connected, 10e-6);
  ASSERT_TRUE(t.path);
  std::printf("Pore2Chip: widest path narrowest at %.1f px (x = %.4g m, y = %.4g m)\n", t.width_m / 10e-6, t.x_m, t.y_m);
  RunOutput out;
  EXPECT_GE(checkThroats(maskProblem(pores.solid_connected, 10e-6, 0.5), "numerics.cells_per_pixel", 0.5, out, true), 1.0);
}
