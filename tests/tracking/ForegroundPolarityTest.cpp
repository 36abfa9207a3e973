// Automatic polarity from what moves: the
// micromodel's grains and deposits are dark whatever the particles are, and a deposit
// that arrives mid-video is in the median background but missing from the early frames,
// where it looks like a bright spot. Unit (< 1 s).
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "mmval/tracking/Detect.hpp"

namespace mmval::tracking {
namespace {

void addSpot(cv::Mat& img, double x, double y, double amplitude, double sigma) {
  for (int r = std::max(0, int(y) - 6); r <= std::min(img.rows - 1, int(y) + 6); ++r)
    for (int c = std::max(0, int(x) - 6); c <= std::min(img.cols - 1, int(x) + 6); ++c)
      img.at<float>(r, c) += static_cast<float>(amplitude * std::exp(-((c - x) * (c - x) + (r - y) * (r - y)) / (2 * sigma * sigma)));
}

// 24 frames of 120 x 160: a dark grain band, 12 dark deposit clusters (three spots each)
// that arrive at frame 8 (so the median holds them and frames 0-7 lack them), and 4
// moving particles of `particle_amplitude` that enter after frame 0 (the first frame has
// none, as the rendered micromodel video), camera noise of 2 %.
std::vector<cv::Mat> video(double particle_amplitude) {
  std::mt19937_64 rng(11);
  std::normal_distribution<double> noise(0.0, 0.02);
  std::uniform_real_distribution<double> ux(10, 150), uy(40, 110);
  std::vector<cv::Point2d> clusters;
  for (int k = 0; k < 12; ++k) clusters.push_back({ux(rng), uy(rng)});
  std::vector<cv::Mat> frames;
  for (int f = 0; f < 24; ++f) {
    cv::Mat img(120, 160, CV_32F, cv::Scalar(0.8));
    img(cv::Rect(0, 0, 160, 30)).setTo(0.2);  // grain
    if (f >= 8)
      for (const auto& c : clusters)
        for (int s = 0; s < 3; ++s) addSpot(img, c.x + 1.5 * s, c.y + (s % 2), -0.5, 1.3);
    if (f > 0)
      for (int p = 0; p < 4; ++p) addSpot(img, 10 + 6.0 * f + 3 * p, 45 + 15 * p, particle_amplitude, 1.3);
    for (auto it = img.begin<float>(); it != img.end<float>(); ++it) *it += static_cast<float>(noise(rng));
    frames.push_back(img);
  }
  return frames;
}

TEST(Detect, PolarityFromMovingForegroundIgnoresDarkStaticClusters) {
  // Dark particles among dark grains and dark clusters: dark, with the frames' own median
  // as background and with an empty one.
  const auto dark = video(-0.5);
  EXPECT_EQ(guessPolarity(dark, cv::Mat()), Polarity::dark);
  // The first frame alone sees only the clusters' absence (bright): the failure this fixes.
  cv::Mat median_bg(dark[0].size(), CV_32F);
  for (int r = 0; r < median_bg.rows; ++r)
    for (int c = 0; c < median_bg.cols; ++c) {
      std::vector<float> v;
      for (const auto& f : dark) v.push_back(f.at<float>(r, c));
      std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
      median_bg.at<float>(r, c) = v[v.size() / 2];
    }
  EXPECT_EQ(guessPolarity(dark, median_bg), Polarity::dark);
  EXPECT_EQ(guessPolarity(dark[0], median_bg), Polarity::bright) << "single-frame guess (kept for detect())";
  // Bright particles in the same dark scene: bright.
  EXPECT_EQ(guessPolarity(video(+0.5), cv::Mat()), Polarity::bright);
}

}  // namespace
}  // namespace mmval::tracking
