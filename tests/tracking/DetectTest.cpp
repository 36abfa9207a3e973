// Detection (Detect.hpp) against spots rendered at known sub-pixel positions.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <opencv2/core.hpp>

#include "mmval/tracking/Detect.hpp"

namespace mmval::tracking {
namespace {

/// Clean Gaussian spots at known sub-pixel positions on a flat background.
cv::Mat spots(const std::vector<cv::Point2d>& at, double sigma, double amplitude, double noise, unsigned seed) {
  cv::Mat img(120, 160, CV_32F, cv::Scalar(0.8));
  for (const auto& p : at)
    for (int y = 0; y < img.rows; ++y)
      for (int x = 0; x < img.cols; ++x)
        img.at<float>(y, x) -= static_cast<float>(amplitude * std::exp(-((x - p.x) * (x - p.x) + (y - p.y) * (y - p.y)) / (2 * sigma * sigma)));
  std::mt19937 rng(seed);
  std::normal_distribution<double> N(0, noise);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) img.at<float>(y, x) += static_cast<float>(N(rng));
  return img;
}

double rmseOf(const std::vector<cv::Point2d>& truth, const std::vector<Detection>& found, int& matched) {
  double se = 0;
  matched = 0;
  for (const auto& t : truth) {
    double best = 1e9;
    for (const auto& d : found) best = std::min(best, std::hypot(d.x - t.x, d.y - t.y));
    if (best < 2) {
      se += best * best;
      ++matched;
    }
  }
  return matched ? std::sqrt(se / matched) : 1e9;
}

/// 35 spot positions on a 7 x 5 grid, 20 px apart, each offset by a random sub-pixel amount.
std::vector<cv::Point2d> gridOfSpots(unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(0, 1);
  std::vector<cv::Point2d> truth;
  for (int gy = 0; gy < 5; ++gy)
    for (int gx = 0; gx < 7; ++gx) truth.push_back({15 + gx * 20 + U(rng), 15 + gy * 20 + U(rng)});
  return truth;
}

TEST(Detect, SubPixelLocalisationOnCleanSpots) {
  const std::vector<cv::Point2d> truth = gridOfSpots(11);
  const cv::Mat background(120, 160, CV_32F, cv::Scalar(0.8));
  DetectOptions o;
  o.blur_sigma = 1.0;
  int matched = 0;
  // Noise-free: the intensity-weighted centroid recovers sub-pixel positions to
  // far better than Crocker & Grier's ~0.05 px (reference-data/tracking-accuracy.toml).
  o.refinement = Refinement::intensity;
  const double intensity = rmseOf(truth, detect(spots(truth, 1.5, 0.4, 0.0, 1), background, Polarity::dark, o), matched);
  EXPECT_EQ(matched, 35);
  EXPECT_LT(intensity, 0.01);
  // The contour centroid of the thresholded blob is pixel-quantised: worse.
  o.refinement = Refinement::moments;
  const double moments = rmseOf(truth, detect(spots(truth, 1.5, 0.4, 0.0, 1), background, Polarity::dark, o), matched);
  EXPECT_EQ(matched, 35);
  EXPECT_GT(moments, intensity);
  // With 2 % camera noise the refined centroid still stays within 0.1 px.
  o.refinement = Refinement::intensity;
  const double noisy = rmseOf(truth, detect(spots(truth, 1.5, 0.4, 0.02, 2), background, Polarity::dark, o), matched);
  EXPECT_EQ(matched, 35);
  EXPECT_LT(noisy, 0.1);
  std::printf("localisation RMSE: intensity %.4f px, moments %.4f px, intensity with noise %.4f px\n", intensity, moments, noisy);
}

TEST(Detect, GaussianFitLocalisesNoisySpotsNearTheCramerRaoBound) {
  // detect.refinement = "gaussian": a least-squares Gaussian spot fit after the centroid. For a
  // Gaussian spot of amplitude A on white noise of std sn (1 px pixels), the Cramer-Rao bound on
  // each coordinate is sn / A * sqrt(2 / pi) (Fisher information sum (dI/dx)^2 = pi A^2 / 2,
  // independent of the spot's sigma): 0.040 px at A = 0.4, sn = 0.02. A least-squares fit on the
  // raw pixels is efficient up to the fitted background and width; it works on the blurred signal
  // here, whose correlated noise costs a little more: within 1.5x the bound, 2D RMSE over sqrt 2.
  const std::vector<cv::Point2d> truth = gridOfSpots(7);
  const cv::Mat background(120, 160, CV_32F, cv::Scalar(0.8));
  DetectOptions o;
  o.blur_sigma = 1.0;
  o.refinement = Refinement::gaussian;
  const double bound = 0.02 / 0.4 * std::sqrt(2.0 / M_PI);
  double se = 0;
  int n = 0;
  for (unsigned seed = 3; seed < 7; ++seed) {
    int matched = 0;
    const double r = rmseOf(truth, detect(spots(truth, 1.5, 0.4, 0.02, seed), background, Polarity::dark, o), matched);
    EXPECT_EQ(matched, 35);
    se += r * r * matched;
    n += matched;
  }
  const double per_axis = std::sqrt(se / n) / std::sqrt(2.0);
  std::printf("gaussian fit: %.4f px per axis, Cramer-Rao bound %.4f px\n", per_axis, bound);
  EXPECT_LT(per_axis, 1.5 * bound);
  EXPECT_GT(per_axis, 0.8 * bound) << "below the bound: the test's noise is not what it says";
}

TEST(Detect, PolarityIsGuessedAndBrightParticlesFound) {
  const std::vector<cv::Point2d> truth = {{40.3, 50.7}, {100.2, 30.1}};
  cv::Mat dark = spots(truth, 1.5, 0.4, 0.0, 1);
  const cv::Mat background(120, 160, CV_32F, cv::Scalar(0.8));
  EXPECT_EQ(guessPolarity(dark, background), Polarity::dark);
  cv::Mat bright = 1.6 - dark;  // bright spots on a 0.8 background
  EXPECT_EQ(guessPolarity(bright, background), Polarity::bright);
  int matched = 0;
  rmseOf(truth, detect(bright, background, Polarity::automatic, DetectOptions{}), matched);
  EXPECT_EQ(matched, 2);
}

}  // namespace
}  // namespace mmval::tracking
