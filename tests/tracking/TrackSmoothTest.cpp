// Along-track regularisation (TrackSmooth.hpp) against what a least-squares
// quadratic must do: reproduce quadratic motion exactly, shrink white
// localisation noise by the Savitzky-Golay variance factor, and leave resting
// stretches, short stretches and other tracks alone.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "mmval/tracking/TrackSmooth.hpp"

namespace mmval::tracking {
namespace {

constexpr double kPixel = 2e-6;  // m per px

TrackPoint at(std::int64_t particle, std::int64_t frame, double x, double y, const char* state = "") {
  TrackPoint p;
  p.particle = particle;
  p.frame = frame;
  p.x_px = x;
  p.y_px = y;
  p.x = x * kPixel;
  p.y = y * kPixel;
  p.state = state;
  return p;
}

double quadX(double f) { return 3.0 + 2.5 * f - 0.04 * f * f; }
double quadY(double f) { return -1.0 + 0.3 * f + 0.02 * f * f; }

TEST(TrackSmooth, ReproducesQuadraticMotionExactlyWithGaps) {
  Tracks t;
  // Frames with gaps (gap closing leaves holes in a track).
  for (std::int64_t f : {0, 1, 2, 4, 5, 6, 9, 10, 11, 12}) t.points.push_back(at(1, f, quadX(f), quadY(f)));
  const SmoothStats s = smoothTracks(t, 2, kPixel);
  EXPECT_EQ(s.points, 10);
  for (const auto& p : t.points) {
    EXPECT_NEAR(p.x_px, quadX(static_cast<double>(p.frame)), 1e-9);
    EXPECT_NEAR(p.y_px, quadY(static_cast<double>(p.frame)), 1e-9);
    EXPECT_NEAR(p.x, p.x_px * kPixel, 1e-18);  // metres follow pixels
  }
}

TEST(TrackSmooth, ShrinksWhiteNoiseByTheSavitzkyGolayFactor) {
  // Interior points of a 5-point quadratic fit: error variance x 17/35; 7 points: x 7/21
  // (sum of squared Savitzky-Golay weights). 4000 tracks of 20 frames, sigma 0.3 px.
  for (const auto& [hw, factor] : {std::pair{2, 17.0 / 35.0}, std::pair{3, 7.0 / 21.0}}) {
    std::mt19937 rng(5);
    std::normal_distribution<double> noise(0.0, 0.3);
    Tracks t;
    for (std::int64_t id = 0; id < 4000; ++id)
      for (std::int64_t f = 0; f < 20; ++f) t.points.push_back(at(id, f, quadX(f) + noise(rng), quadY(f) + noise(rng)));
    smoothTracks(t, hw, kPixel);
    double sum = 0;
    long n = 0;
    for (const auto& p : t.points) {
      if (p.frame < hw || p.frame >= 20 - hw) continue;  // interior: centred windows only
      const double ex = p.x_px - quadX(static_cast<double>(p.frame)), ey = p.y_px - quadY(static_cast<double>(p.frame));
      sum += ex * ex + ey * ey;
      ++n;
    }
    const double ratio = sum / (2.0 * n) / (0.3 * 0.3);
    // ~2 x 64,000 samples: the variance estimate's relative standard error is ~0.4 %
    // (neighbouring points share noise, so allow 3 %).
    EXPECT_NEAR(ratio, factor, 0.03 * factor) << "half window " << hw;
  }
}

TEST(TrackSmooth, LeavesRestsShortStretchesAndOffAlone) {
  Tracks t;
  // Track 1: 6 moving points, then 4 at rest ("deposited"), noisy everywhere.
  const double wobble[] = {0.2, -0.3, 0.25, -0.1, 0.3, -0.2, 0.1, -0.1, 0.2, -0.2};
  for (std::int64_t f = 0; f < 10; ++f)
    t.points.push_back(at(1, f, (f < 6 ? 2.0 * f : 10.0) + wobble[f], 5.0, f < 6 ? "" : "deposited"));
  // Track 2: 3 points only: a quadratic through 3 points smooths nothing; left as measured.
  for (std::int64_t f = 0; f < 3; ++f) t.points.push_back(at(2, f, 1.0 + wobble[f], 2.0));
  const Tracks before = t;
  const SmoothStats none = smoothTracks(t, 0, kPixel);
  EXPECT_EQ(none.points, 0);
  for (std::size_t k = 0; k < t.points.size(); ++k) EXPECT_EQ(t.points[k].x_px, before.points[k].x_px);

  const SmoothStats s = smoothTracks(t, 2, kPixel);
  EXPECT_EQ(s.points, 6);
  EXPECT_EQ(s.skipped, 3);
  for (std::size_t k = 6; k < t.points.size(); ++k) EXPECT_EQ(t.points[k].x_px, before.points[k].x_px) << "point " << k;
  // The moving stretch got closer to its straight line (x = 2 f) on the whole.
  double err_before = 0, err_after = 0;
  for (std::size_t k = 0; k < 6; ++k) {
    err_before += std::pow(before.points[k].x_px - 2.0 * static_cast<double>(k), 2);
    err_after += std::pow(t.points[k].x_px - 2.0 * static_cast<double>(k), 2);
  }
  EXPECT_LT(err_after, 0.7 * err_before);
}

}  // namespace
}  // namespace mmval::tracking
