#include <cmath>

#include <gtest/gtest.h>

#include "mmval/simulate/Geometry.hpp"

using namespace mmval::simulate;

TEST(Geometry, CircleDistanceIsExact) {
  const Circles c({{0.0, 0.0, 1.0}});
  EXPECT_EQ(c.bodyAt(0.5, 0.5), 0);
  EXPECT_EQ(c.bodyAt(0.8, 0.8), -1);
  EXPECT_NEAR(c.distanceAlong(-2.0, 0.0, 0, +1, 5.0), 1.0, 1e-14);
  EXPECT_NEAR(c.distanceAlong(0.0, 3.0, 1, -1, 5.0), 2.0, 1e-14);
  EXPECT_NEAR(c.distanceAlong(-2.0, 0.6, 0, +1, 5.0), 2.0 - 0.8, 1e-14);
  EXPECT_DOUBLE_EQ(c.distanceAlong(-2.0, 0.0, 0, -1, 5.0), 5.0);  // looking away
  // The generic bisection (segment ending inside the body) agrees with the closed form.
  EXPECT_NEAR(c.Shape::distanceAlong(-2.0, 0.6, 0, +1, 1.5), 1.2, 1e-9);
}

TEST(Geometry, PeriodicCirclesRepeat) {
  const Circles c({{0.5, 0.5, 0.2}}, 1.0, 1.0);
  EXPECT_EQ(c.bodyAt(1.5, -0.5), 0);
  EXPECT_NEAR(c.distanceAlong(0.95, 0.5, 0, +1, 0.9), 0.35, 1e-14);  // the next image at x = 1.5
}

TEST(Geometry, MaskStaircase) {
  Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic> m = Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic>::Constant(4, 4, false);
  m(0, 3) = true;  // top-right pixel
  const MaskShape s(m, 1e-6);
  EXPECT_EQ(s.bodyAt(3.5e-6, 3.5e-6), 0);
  EXPECT_EQ(s.bodyAt(3.5e-6, 2.5e-6), -1);
  EXPECT_NEAR(s.distanceAlong(1.2e-6, 3.5e-6, 0, +1, 1e-5), 1.8e-6, 1e-15);
  EXPECT_NEAR(s.distanceAlong(3.5e-6, 1.0e-6, 1, +1, 1e-5), 2.0e-6, 1e-15);
  EXPECT_DOUBLE_EQ(s.distanceAlong(1.2e-6, 1.5e-6, 0, +1, 1e-5), 1e-5);
}
