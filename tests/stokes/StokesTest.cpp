// mmval's Stokes solver against exact solutions and Sangani & Acrivos (1982).
#include <gtest/gtest.h>

#include <cmath>

#include "mmval/stokes/Stokes.hpp"

namespace mmval::stokes {
namespace {

double channelFlow(int n, double depth) {
  Problem p;
  p.nx = 4;
  p.ny = n;
  p.h = 100e-6 / n;
  p.walls_y = true;
  p.viscosity = 1e-3;
  p.pressure_gradient = 1e4;
  p.depth = depth;
  return solve(p).superficial_u * 100e-6;
}

TEST(Stokes, PlanePoiseuilleConvergesAtSecondOrder) {
  const double exact = 1e4 * std::pow(100e-6, 3) / (12 * 1e-3);  // G W^3 / (12 mu)
  const double e16 = std::abs(channelFlow(16, 0) - exact) / exact;
  const double e32 = std::abs(channelFlow(32, 0) - exact) / exact;
  EXPECT_LT(e32, 0.005);
  EXPECT_NEAR(e16 / e32, 4.0, 0.3);  // halving h divides the error by 4
}

TEST(Stokes, DepthAveragedChannelMatchesTheBrinkmanSolution) {
  // u(y) = G / (mu k^2) (1 - cosh(k (y - W/2)) / cosh(k W / 2)), k^2 = 12 / h^2; W = 100 um, h = 20 um.
  const double W = 100e-6, h = 20e-6, k = std::sqrt(12.0) / h, G = 1e4, mu = 1e-3;
  const double exact = G / (mu * k * k) * (1 - std::tanh(k * W / 2) / (k * W / 2)) * W;
  EXPECT_NEAR(channelFlow(128, h), exact, 0.002 * exact);
}

TEST(Stokes, SquareArrayApproachesSanganiAcrivos) {
  // phi = 0.2: F* = 51.53. The volume-fraction immersed boundary converges at first order from above.
  const double L = 1e-4, a = L * std::sqrt(0.2 / M_PI), mu = 1e-3;
  auto fstar = [&](int n) {
    Problem p;
    p.nx = p.ny = n;
    p.h = L / n;
    p.viscosity = mu;
    setSolidFromIndicator(p, [&](double x, double y) { return std::hypot(x - L / 2, y - L / 2) < a; });
    const Solution s = solve(p);
    EXPECT_LT(s.max_divergence, 1e-9);  // MAC: discretely divergence-free
    return L * L / (mu * s.superficial_u);
  };
  const double f32 = fstar(32), f128 = fstar(128);
  EXPECT_GT(f32, f128);
  EXPECT_NEAR(f128, 51.53, 0.035 * 51.53);  // measured +2.8 % at 128 x 128
}

TEST(Stokes, AllSolidGivesNoFlowAndNoNaN) {
  Problem p;
  p.nx = p.ny = 8;
  p.h = 1e-6;
  setSolidFromIndicator(p, [](double, double) { return true; });
  const Solution s = solve(p);
  EXPECT_TRUE(s.u.allFinite());
  EXPECT_LT(std::abs(s.superficial_u), 1e-6 * 1.0 * p.h * p.h / p.viscosity);
}

}  // namespace
}  // namespace mmval::stokes
