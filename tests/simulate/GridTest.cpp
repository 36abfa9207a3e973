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
