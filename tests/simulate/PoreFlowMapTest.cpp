// The pore flow of synthetic videos (PoreFlowMap) against plane Poiseuille flow:
// an image without grains is a channel with no-slip walls at its top and bottom
// edges, periodic along x, whose exact profile is u(y) = 6 U y (h - y) / h^2 for
// the mean speed U (maximum 1.5 U at mid-depth, no cross-stream velocity).
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include <opencv2/core.hpp>

#include "mmval/simulate/PoreFlowMap.hpp"

namespace mmval::simulate {
namespace {

constexpr int kWidthPx = 60, kHeightPx = 40;
constexpr double kMeanSpeed = 2.0;  // px per frame
// 40 cells across the channel: the MAC grid's second-order wall error is well
// under 1 % of the maximum; 2 % leaves room for the bilinear sampling.
constexpr double kProfileTolerance = 0.02;

double poiseuille(double y) { return 6 * kMeanSpeed * y * (kHeightPx - y) / (kHeightPx * kHeightPx); }

TEST(PoreFlowMap, OpenImageIsPlanePoiseuilleAtTheRequestedMeanSpeed) {
  const PoreFlowMap flow(cv::Mat::zeros(kHeightPx, kWidthPx, CV_8U), kMeanSpeed);
  double sum = 0;
  for (int y = 0; y < kHeightPx; ++y)
    for (int x = 0; x < kWidthPx; ++x) sum += flow.at(x + 0.5, y + 0.5).x;
  EXPECT_NEAR(sum / (kWidthPx * kHeightPx), kMeanSpeed, 0.01 * kMeanSpeed);  // the scaling's own definition, sampled on every pixel
  for (const double y : {2.5, 10.5, 20.0, 29.5, 37.5}) {
    const cv::Point2d u = flow.at(17.0, y);
    EXPECT_NEAR(u.x, poiseuille(y), kProfileTolerance * 1.5 * kMeanSpeed) << "y = " << y << " px";
    EXPECT_NEAR(u.y, 0.0, 1e-6 * kMeanSpeed) << "y = " << y << " px";
  }
  // Periodic along x: the same profile at every x.
  EXPECT_NEAR(flow.at(3.0, 20.0).x, flow.at(51.0, 20.0).x, 1e-6 * kMeanSpeed);
}

TEST(PoreFlowMap, AGrainWallAcrossTheImageIsRefused) {
  cv::Mat grains = cv::Mat::zeros(kHeightPx, kWidthPx, CV_8U);
  grains.colRange(25, 30).setTo(255);  // no pore path from the left edge to the right
  EXPECT_THROW(PoreFlowMap(grains, kMeanSpeed), std::runtime_error);
}

}  // namespace
}  // namespace mmval::simulate
