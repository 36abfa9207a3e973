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
