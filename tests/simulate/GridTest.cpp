#include <cmath>

#include <gtest/gtest.h>

#include "mmval/simulate/Grid.hpp"

using namespace mmval::simulate;

TEST(Grid, UniformAxis) {
  const Axis a = uniformAxis(0, 2, 8);
  EXPECT_EQ(a.cells(), 8);
  EXPECT_NEAR(a.width(3), 0.25, 1e-15);
  EXPECT_NEAR(a.centre(0), 0.125, 1e-15);
  EXPECT_EQ(a.cellOf(1.01), 4);
  EXPECT_EQ(a.cellOf(-5), 0);
  EXPECT_EQ(a.cellOf(5), 7);
  EXPECT_THROW(uniformAxis(1, 0, 4), std::invalid_argument);
}

TEST(Grid, RefinedAxisSpansAndGrowsSmoothly) {
  const Axis a = refinedAxis(0, 2.2, 0.125, 0.35, 0.005, 1.05, 0.02);
  EXPECT_DOUBLE_EQ(a.lo(), 0.0);
  EXPECT_DOUBLE_EQ(a.hi(), 2.2);
  EXPECT_NEAR(a.minWidth(), 0.005, 1e-12);
  EXPECT_LE(a.maxWidth(), 0.02 * 1.05);
  for (int i = 1; i < a.cells(); ++i) {
    const double r = a.width(i) / a.width(i - 1);
    EXPECT_LT(std::max(r, 1 / r), 1.11) << "cell " << i;  // growth ratio after the rescaling that makes the ends fit
  }
  // The refined box is uniform.
  const int i0 = a.cellOf(0.13);
  EXPECT_NEAR(a.width(i0), a.width(i0 + 10), 1e-12);
}

TEST(Grid, AnchoredRefinedAxisHasAFaceAtTheAnchorAndNoSlivers) {
  // Schaefer-Turek's channel (0.41 m, cylinder centre 0.2 m) refined across its whole height at
  // h = pi D / 64: a face at the centre, cells of exactly h mirrored about it, and the remainders
  // at the walls (0.2 m and 0.21 m are not whole multiples of h) no thinner than h / 2.
  const double h = M_PI * 0.1 / 64, cy = 0.2;
  const Axis a = refinedAxis(0, 0.41, 0, 0.41, h, 1.05, 4 * h, cy);
  EXPECT_DOUBLE_EQ(a.lo(), 0.0);
  EXPECT_DOUBLE_EQ(a.hi(), 0.41);
  const int k = a.cellOf(cy + 0.25 * h);
  EXPECT_NEAR(a.face(k), cy, 1e-12);
  for (int m = 1; m < 30; ++m) {
    EXPECT_NEAR(a.width(k + m - 1), h, 1e-12) << "cell " << m << " above the centre";
    EXPECT_NEAR(cy - a.face(k - m), a.face(k + m) - cy, 1e-12) << "face " << m << " from the centre";
  }
  EXPECT_GE(a.minWidth(), 0.5 * h);
  EXPECT_LE(a.maxWidth(), 1.5 * h);
  // A box inside the axis: trimmed to whole cells about the anchor, stretched outside as before.
  const Axis b = refinedAxis(0, 2.2, 0.125, 0.35, 0.005, 1.05, 0.02, 0.2);
  const int kb = b.cellOf(0.2 + 0.001);
  EXPECT_NEAR(b.face(kb), 0.2, 1e-12);
  EXPECT_NEAR(b.width(kb - 15), 0.005, 1e-12);
  EXPECT_NEAR(b.width(kb + 29), 0.005, 1e-12);
  EXPECT_DOUBLE_EQ(b.hi(), 2.2);
  EXPECT_THROW(refinedAxis(0, 1, 0.2, 0.4, 0.01, 1.05, 0.04, 0.5), std::invalid_argument);
}

TEST(Grid, WallGradedAxisStartsAtTheWallSpacingAndRejoinsTheAxis) {
  // The channel of Schaefer & Turek's 2D-2 with uniform cells h = H / 84, graded to h / 3 at both walls.
  const double H = 0.41, h = H / 84;
  const Axis base = uniformAxis(0, H, 84);
  const Axis a = wallGradedAxis(base, h / 3, 1.05);
  EXPECT_DOUBLE_EQ(a.lo(), 0.0);
  EXPECT_DOUBLE_EQ(a.hi(), H);
  // First and last cells: h / 3 up to the rescaling onto an original face (at most half a cell over the layer).
  EXPECT_NEAR(a.width(0) / (h / 3), 1.0, 0.1);
  EXPECT_NEAR(a.width(a.cells() - 1) / (h / 3), 1.0, 0.1);
  // ln 3 / ln 1.05 ~ 22.5 graded cells a side replace ~ 14.5 cells of h.
  EXPECT_GT(a.cells(), 84 + 2 * 5);
  EXPECT_LT(a.cells(), 84 + 2 * 12);
  for (int i = 1; i < a.cells(); ++i) {
    const double r = a.width(i) / a.width(i - 1);
    EXPECT_LT(std::max(r, 1 / r), 1.1) << "cell " << i;
  }
  // The middle keeps the original faces exactly.
  const int mid = a.cellOf(0.2);
  EXPECT_NEAR(a.width(mid), h, 1e-12);
  EXPECT_NEAR(std::remainder(a.face(mid), h), 0.0, 1e-12);
  // Ends already finer than h_end are left alone; bad arguments are refused.
  EXPECT_EQ(wallGradedAxis(base, 2 * h, 1.05).cells(), 84);
  EXPECT_THROW(wallGradedAxis(base, 0.0, 1.05), std::invalid_argument);
  EXPECT_THROW(wallGradedAxis(base, h / 2, 1.0), std::invalid_argument);
}

TEST(Grid, InnerRefinedAxisSplitsTheBoxKeepsTheCentreFaceAndGradesBack) {
  // 2D-2's x axis at h = pi D / 64 (face through the centre 0.2 m, cells of h from the inlet),
  // then cells of h / 2 within 1 D of the centre, graded back to h by 1.05 per cell.
  const double D = 0.1, h = M_PI * D / 64, cx = 0.2;
  const Axis base = refinedAxis(0, 2.2, 0, cx + 4 * D, h, 1.05, 4 * h, cx);
  const Axis a = innerRefinedAxis(base, cx - D, cx + D, 2, 1.05);
  EXPECT_DOUBLE_EQ(a.lo(), 0.0);
  EXPECT_DOUBLE_EQ(a.hi(), 2.2);
  // The centre is still a face, with cells of exactly h / 2 mirrored about it out to ~1 D.
  const int k = a.cellOf(cx + 0.1 * h);
  EXPECT_NEAR(a.face(k), cx, 1e-12);
  const int n_fine = static_cast<int>(D / (0.5 * h)) - 1;
  for (int m = 1; m <= n_fine; ++m) {
    EXPECT_NEAR(a.width(k + m - 1), 0.5 * h, 1e-12) << "cell " << m << " downstream of the centre";
    EXPECT_NEAR(cx - a.face(k - m), a.face(k + m) - cx, 1e-12) << "face " << m << " from the centre";
  }
  // Smooth about the box: neighbours differ by at most the ratio (+ the snap's rescaling). (The
  // base axis's first cell holds the inlet's remainder, up to 1.5 h.)
  for (int i = a.cellOf(cx - 1.8 * D); i <= a.cellOf(cx + 1.8 * D); ++i) {
    const double r = a.width(i) / a.width(i - 1);
    EXPECT_LT(std::max(r, 1 / r), 1.1) << "cell " << i;
  }
  // Faces of the base axis away from the box are kept: the first cell and the wake's cells of h.
  EXPECT_DOUBLE_EQ(a.width(0), base.width(0));
  const int w = a.cellOf(cx + 3 * D);
  EXPECT_NEAR(a.width(w), h, 1e-12);
  // ln 2 / ln 1.05 ~ 14 graded cells a side stand in for ~ 10 cells of h: about 2 D / h + 8 more cells.
  EXPECT_GT(a.cells(), base.cells() + static_cast<int>(2 * D / h) + 4);
  EXPECT_LT(a.cells(), base.cells() + static_cast<int>(2 * D / h) + 14);
  EXPECT_EQ(innerRefinedAxis(base, cx - D, cx + D, 1, 1.05).cells(), base.cells());
  EXPECT_THROW(innerRefinedAxis(base, cx, cx + 0.1 * h, 2, 1.05), std::invalid_argument);
  EXPECT_THROW(innerRefinedAxis(base, cx - D, cx + D, 0, 1.05), std::invalid_argument);
  // Upstream cells growing by 1.05 from 0.75 D before the centre: a layer growing by 1.05 never
  // catches up with them, so the fine cells run to the inlet (each cell split in two, no jump).
  const Axis stretched = refinedAxis(0, 2.2, cx - 0.75 * D, cx + 4 * D, h, 1.05, 4 * h, cx);
  const Axis s = innerRefinedAxis(stretched, cx - D, cx + D, 2, 1.05);
  EXPECT_NEAR(s.width(0), 0.5 * stretched.width(0), 1e-12);
  EXPECT_NEAR(s.width(1), 0.5 * stretched.width(0), 1e-12);
  EXPECT_EQ(s.cellOf(cx - 0.1 * h), 2 * stretched.cellOf(cx - 0.1 * h) + 1);
  EXPECT_NEAR(s.width(s.cellOf(cx + 3 * D)), h, 1e-12);
}
