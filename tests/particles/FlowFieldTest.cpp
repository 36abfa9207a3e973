// Flow fields: exact answers for analytic fields, interpolation exact for linear data.
#include <gtest/gtest.h>

#include "mmval/particles/FlowField.hpp"

namespace mmval::particles {
namespace {

TEST(FlowField, PoiseuilleProfileHasMeanOneAndMaxOnePointFive) {
  double s = 0;
  const int n = 100000;
  for (int i = 0; i < n; ++i) s += poiseuilleProfile((i + 0.5) / n * 20e-6, 20e-6);
  EXPECT_NEAR(s / n, 1.0, 1e-9);  // midpoint rule on a parabola: error ~1/n^2
  EXPECT_NEAR(poiseuilleProfile(10e-6, 20e-6), 1.5, 1e-12);
  EXPECT_EQ(poiseuilleProfile(-1e-9, 20e-6), 0.0);
}

TEST(FlowField, HeleShawChannelVelocityWallsAndDistance) {
  HeleShawChannel ch(1e-3, 200e-6, 20e-6, 7e-4);
  EXPECT_NEAR(ch.velocityAt({1e-4, 1e-4, 5e-6}).x(), 6 * 7e-4 * 5e-6 * 15e-6 / (20e-6 * 20e-6), 1e-15);
  EXPECT_TRUE(ch.isSolid(1e-4, -1e-9));
  EXPECT_TRUE(ch.isSolid(1e-4, 201e-6));
  EXPECT_NEAR(ch.wallDistance(1e-4, 30e-6), 30e-6, 1e-18);
  EXPECT_NEAR(ch.wallDistance(1e-4, 190e-6), 10e-6, 1e-18);
  EXPECT_NEAR(ch.wallNormal(1e-4, 190e-6).y(), -1.0, 1e-12);
  EXPECT_EQ(ch.velocityAt({1e-4, -1e-6, 5e-6}).norm(), 0.0);
}

TEST(FlowField, GriddedFlowInterpolatesLinearFieldsExactlyAndBumpsVersion) {
  const int nx = 11, ny = 6;
  GriddedFlow g(nx, ny, 0.0, 0.0, 1e-5, 2e-5);
  EXPECT_EQ(g.version(), 0u);
  std::vector<double> ux(nx * ny), uy(nx * ny), h(nx * ny, 20e-6);
  std::vector<std::uint8_t> solid(nx * ny, 0);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      ux[j * nx + i] = 1e-3 + 2.0 * i * 1e-5 + 3.0 * j * 2e-5;
      uy[j * nx + i] = -1.0 * i * 1e-5;
    }
  g.update(ux, uy, h, solid);
  EXPECT_EQ(g.version(), 1u);
  const double x = 3.3e-5, y = 7.1e-5;
  EXPECT_NEAR(g.meanVelocity(x, y).x(), 1e-3 + 2 * x + 3 * y, 1e-15);
  EXPECT_NEAR(g.meanVelocity(x, y).y(), -x, 1e-15);
  EXPECT_NEAR(g.depth(x, y), 20e-6, 1e-18);
  EXPECT_THROW(g.update(ux, uy, h, std::vector<std::uint8_t>(3)), std::invalid_argument);
}

TEST(FlowField, GriddedFlowWallDistanceOfAChannelMask) {
  // Solid rows j = 0 and j = 10: walls half way to the first fluid rows, at y = 0.5 dy and 9.5 dy.
  const int nx = 8, ny = 11;
  const double dy = 1e-6;
  GriddedFlow g(nx, ny, 0.0, 0.0, dy, dy);
  std::vector<double> z(nx * ny, 0.0), h(nx * ny, 20e-6);
  std::vector<std::uint8_t> solid(nx * ny, 0);
  for (int i = 0; i < nx; ++i) solid[i] = solid[10 * nx + i] = 1;
  g.update(z, z, h, solid);
  EXPECT_NEAR(g.wallDistance(4e-6, 3e-6), 2.5e-6, 1e-12);
  EXPECT_NEAR(g.wallDistance(4e-6, 5e-6), 4.5e-6, 1e-12);
  EXPECT_NEAR(g.wallNormal(4e-6, 3.2e-6).y(), 1.0, 1e-6);
  EXPECT_TRUE(g.isSolid(4e-6, 0.2e-6));
  EXPECT_FALSE(g.isSolid(4e-6, 0.7e-6));
}

}  // namespace
}  // namespace mmval::particles
