// The tracker's pictures: speeds binned on the pore space land in the right
// bins with the right colour, and steps are drawn where they are, coloured by
// speed, against hand-built statistics.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "mmval/tracking/TrackImages.hpp"

namespace mmval::tracking {
namespace {

constexpr double kPixel = 1e-6;  // m per px

Step step(std::int64_t particle, double x_px, double y_px, double vx) {
  Step s;
  s.particle = particle;
  s.x = x_px * kPixel;
  s.y = y_px * kPixel;
  s.vx = vx;
  s.speed = std::abs(vx);
  return s;
}

cv::Vec3b viridis(int i) {
  cv::Mat ramp(1, 1, CV_8U, cv::Scalar(i)), c;
  cv::applyColorMap(ramp, c, cv::COLORMAP_VIRIDIS);
  return c.at<cv::Vec3b>(0, 0);
}

TEST(TrackImages, SpeedMapBinsStepsByMidpointOnTheSpeedScale) {
  TrackStats s;
  // Bin (col 1, row 0) of 10 px: two steps of 10 and 20 um/s, mean 15; bin (3, 2): 200 steps
  // of 20 um/s set the 99th percentile scale to 20 um/s.
  s.steps.push_back(step(1, 12, 3, 10e-6));
  s.steps.push_back(step(1, 18, 7, 20e-6));
  for (int k = 0; k < 200; ++k) s.steps.push_back(step(2, 35, 25, 20e-6));
  const cv::Mat base(40, 50, CV_8U, cv::Scalar(200));
  cv::Mat counts;
  const cv::Mat img = speedMap(base, s, kPixel, 10, &counts);
  ASSERT_EQ(counts.rows, 4);
  ASSERT_EQ(counts.cols, 5);
  EXPECT_EQ(counts.at<int>(0, 1), 2);
  EXPECT_EQ(counts.at<int>(2, 3), 200);
  EXPECT_EQ(cv::sum(counts)[0], 202);
  EXPECT_EQ(img.rows, 40);
  EXPECT_GT(img.cols, 50);  // colour bar on the right
  // Colour = 0.25 x dimmed base + 0.75 x viridis(speed / scale).
  const auto expect = [&](cv::Point p, double fraction) {
    const cv::Vec3b v = viridis(static_cast<int>(std::lround(255 * fraction)));
    const cv::Vec3b got = img.at<cv::Vec3b>(p);
    for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(got[ch], 0.25 * 200 * 0.55 + 0.75 * v[ch], 1.5) << "channel " << ch << " at " << p;
  };
  expect({15, 5}, 15.0 / 20.0);
  expect({35, 25}, 1.0);
  // An empty bin shows the dimmed base.
  EXPECT_EQ(img.at<cv::Vec3b>(35, 5), cv::Vec3b(110, 110, 110));
}

TEST(TrackImages, VelocityOverlayDrawsEachStepWhereItIs) {
  TrackStats s;
  // One fast horizontal step centred at (20, 10) px: 8 px per 0.1 s frame = 80 um/s.
  for (int k = 0; k < 100; ++k) s.steps.push_back(step(1, 20, 10, 80e-6));
  const cv::Mat base(30, 40, CV_8U, cv::Scalar(0));
  const cv::Mat img = velocityOverlay(base, s, kPixel, 0.1);
  const cv::Vec3b top = viridis(255);
  const cv::Vec3b on = img.at<cv::Vec3b>(10, 20), off = img.at<cv::Vec3b>(20, 20), beyond = img.at<cv::Vec3b>(10, 30);
  for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(on[ch], top[ch], 2) << "on the segment";
  EXPECT_EQ(off, cv::Vec3b(0, 0, 0)) << "away from it";
  EXPECT_EQ(beyond, cv::Vec3b(0, 0, 0)) << "beyond its half length of 4 px";
}

}  // namespace
}  // namespace mmval::tracking
