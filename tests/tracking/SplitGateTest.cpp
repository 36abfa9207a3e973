// The joint fit's split test (SpotFit.cpp, JointFit::splitMergedPairs): two particles
// closer than the seeds' separation make one elongated blob, which the test splits when two
// spots explain it significantly better than one; a lone spot stays one detection. Spots
// rendered at known positions: pairs of equal spots among lone ones at SNR 10.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include <opencv2/core.hpp>

#include "mmval/tracking/Detect.hpp"

namespace mmval::tracking {
namespace {

constexpr double kSigma = 1.5;      // px, the spots' Gaussian sigma
constexpr double kAmplitude = 0.2;  // dark spots on a background of 0.8
constexpr double kNoise = 0.02;     // white noise std: SNR = amplitude / noise = 10

struct SplitCounts {
  int pairs = 0, pairs_found = 0, pairs_more = 0;  // pairs; both found (one detection each); more than two detections
  int singles = 0, singles_duplicated = 0, singles_lost = 0;
  double pair_se = 0;  // squared distances of the found pairs' detections to their truth, px^2
  int pair_points = 0;
};

/// An 8 x 6 grid of sites 24 px apart (sub-pixel offsets); every third site holds a pair of
/// equal spots `separation_sigmas` x sigma apart at a random angle, the others one spot (the
/// detector takes its spots' sigma from the median blob: most spots must be lone ones).
/// A pair counts as found when exactly two detections lie within 3 sigma of it, each truth
/// spot with a detection closer than half their separation; a lone spot is duplicated when
/// more than one detection lies within 3 sigma, lost when none lies within 0.5 px.
SplitCounts detectPairs(double separation_sigmas, unsigned seeds) {
  SplitCounts c;
  for (unsigned seed = 1; seed <= seeds; ++seed) {
    std::mt19937 rng(seed * 7919 + static_cast<unsigned>(separation_sigmas * 100));
    std::uniform_real_distribution<double> U(0, 1);
    std::vector<std::vector<cv::Point2d>> truth;
    const double half = 0.5 * separation_sigmas * kSigma;
    for (int gy = 0; gy < 6; ++gy)
      for (int gx = 0; gx < 8; ++gx) {
        const double cx = 20 + gx * 24 + U(rng), cy = 20 + gy * 24 + U(rng), theta = U(rng) * M_PI;
        if ((gx + gy) % 3 == 0)
          truth.push_back({{cx + half * std::cos(theta), cy + half * std::sin(theta)}, {cx - half * std::cos(theta), cy - half * std::sin(theta)}});
        else
          truth.push_back({{cx, cy}});
      }
    cv::Mat img(164, 212, CV_32F);
    std::normal_distribution<double> N(0, kNoise);
    for (int y = 0; y < img.rows; ++y)
      for (int x = 0; x < img.cols; ++x) {
        double v = 0.8 + N(rng);
        for (const auto& site : truth)
          for (const auto& p : site) {
            const double d2 = (x - p.x) * (x - p.x) + (y - p.y) * (y - p.y);
            if (d2 < 150) v -= kAmplitude * std::exp(-d2 / (2 * kSigma * kSigma));
          }
        img.at<float>(y, x) = static_cast<float>(v);
      }
    const cv::Mat background(img.rows, img.cols, CV_32F, cv::Scalar(0.8));
    DetectOptions o;
    o.blur_sigma = 1.0;
    const std::vector<Detection> dets = detect(img, background, Polarity::dark, o);
    for (const auto& site : truth) {
      int near = 0;
      std::vector<double> best(site.size(), 1e9);
      for (const Detection& d : dets) {
        double closest = 1e9;
        for (std::size_t q = 0; q < site.size(); ++q) {
          const double dist = std::hypot(d.x - site[q].x, d.y - site[q].y);
          closest = std::min(closest, dist);
          best[q] = std::min(best[q], dist);
        }
        if (closest < 3 * kSigma) ++near;
      }
      if (site.size() == 2) {
        ++c.pairs;
        if (near == 2 && best[0] < half && best[1] < half) {
          ++c.pairs_found;
          c.pair_se += best[0] * best[0] + best[1] * best[1];
          c.pair_points += 2;
        }
        if (near > 2) ++c.pairs_more;
      } else {
        ++c.singles;
        if (near > 1) ++c.singles_duplicated;
        if (best[0] > 0.5) ++c.singles_lost;
      }
    }
  }
  return c;
}

TEST(Deblend, ClosePairsAreSplitAndLoneSpotsAreNot) {
  // Measured, 6 seeds, 96 pairs and 192 lone spots per separation, with the pair fit of
  // 8 passes x 2 steps and extrapolation as with the former 8 x 6: pairs found 0 at 1.5
  // sigma, 44 at 1.8, 95 at 2.0, 96 at 2.2 sigma; no lone spot duplicated or lost. Below
  // ~1.6 sigma (2.4 px, with the 1 px blur) two spots do not gain enough over one at this
  // SNR for the test's thresholds (with the thresholds and screens at 0, 93 of the 96
  // pairs at 1.5 sigma split, and 3 of the 192 lone spots too).
  for (const double separation : {1.5, 1.8, 2.0, 2.2}) {
    const SplitCounts c = detectPairs(separation, 6);
    const double rmse = c.pair_points ? std::sqrt(c.pair_se / c.pair_points) : 0.0;
    std::printf("pairs %.1f sigma apart (%.2f px), SNR 10: both found %d of %d (more than two: %d), their RMSE %.3f px; lone spots: %d duplicated, %d lost of %d\n",
                separation, separation * kSigma, c.pairs_found, c.pairs, c.pairs_more, rmse, c.singles_duplicated, c.singles_lost, c.singles);
    EXPECT_EQ(c.singles_duplicated, 0) << separation;  // a lone spot is never split
    EXPECT_EQ(c.singles_lost, 0) << separation;
    EXPECT_EQ(c.pairs_more, 0) << separation;
    if (separation >= 2.0) {
      // Resolved pairs: both found, and placed: a lone spot's Cramer-Rao bound is
      // noise / amplitude x sqrt(2 / pi) = 0.08 px per axis (0.11 px in the plane); the
      // pair's overlap costs more (measured 0.17 px at 2.0 sigma, 0.15 px at 2.2).
      EXPECT_GE(c.pairs_found, (separation >= 2.2 ? 0.97 : 0.9) * c.pairs) << separation;
      EXPECT_LT(rmse, 0.25) << separation;
    }
  }
}

}  // namespace
}  // namespace mmval::tracking
