// Track statistics (TrackMetrics.hpp: analyseTracks) of simulated free Brownian
// motion, whose MSD is 4 D t.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "mmval/tracking/TrackMetrics.hpp"

namespace mmval::tracking {
namespace {

TEST(TrackMetrics, BrownianDiffusionFromTheMsd) {
  // 300 free Brownian particles, D = 0.5 um^2/s, dt = 0.1 s, 100 steps: MSD = 4 D t.
  std::mt19937_64 rng(9);
  const double D = 0.5e-12, dt = 0.1;
  std::normal_distribution<double> step(0, std::sqrt(2 * D * dt));
  Tracks t;
  for (int p = 0; p < 300; ++p) {
    double x = 1e-4, y = 1e-4;
    for (int f = 0; f < 100; ++f) {
      TrackPoint q;
      q.frame = f;
      q.particle = p;
      q.t = f * dt;
      q.x = x;
      q.y = y;
      t.points.push_back(q);
      x += step(rng);
      y += step(rng);
    }
  }
  TrackOptions o;
  o.immobile_distance = 0;  // every particle counts
  const TrackStats s = analyseTracks(t, o);
  std::printf("Brownian: D linear %.4g, D power %.4g um^2/s, alpha %.3f\n", s.msd.d_linear * 1e12, s.msd.d_power * 1e12, s.msd.alpha);
  EXPECT_NEAR(s.msd.d_linear, D, 0.05 * D);
  EXPECT_NEAR(s.msd.alpha, 1.0, 0.05);
}

}  // namespace
}  // namespace mmval::tracking
