// Rests in the middle of a track (issue 3 step 5, issue 7 speeds per region): a
// deposit whose track a passing particle takes over rests for hundreds of frames and
// then moves on. Those resting steps are localisation noise, not motion, and leave the
// velocity statistics as a trailing rest's do. Unit (< 1 s).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "mmval/tracking/TrackMetrics.hpp"

namespace mmval::tracking {
namespace {

TrackPoint at(std::int64_t frame, double t, double x_m, double y_m) {
  TrackPoint p;
  p.frame = frame;
  p.particle = 1;
  p.t = t;
  p.x = x_m;
  p.y = y_m;
  p.x_px = x_m * 1e5;
  p.y_px = y_m * 1e5;
  return p;
}

// 10 um pixels and 40 fps (the rendered micromodel's): 1 px/frame for 30 frames, at rest
// under 0.15 px localisation noise for 200 frames (5 s, with a 0.3 px shift half-way: a
// neighbour depositing alongside), then 1 px/frame again for 30 frames.
TEST(Deposit, RestInsideATrackIsLabelledAndLeftOutOfSpeeds) {
  std::mt19937_64 rng(5);
  std::normal_distribution<double> noise(0.0, 1.5e-6);
  Tracks t;
  double x = 100e-6;
  for (int f = 0; f < 260; ++f) {
    const bool resting = f >= 30 && f < 230;
    if (!resting && f > 0) x += 10e-6;
    const double shift = f >= 130 && f < 230 ? 3e-6 : 0.0;
    const double nx = resting ? noise(rng) : 0.0;
    const double ny = resting ? noise(rng) : 0.0;
    t.points.push_back(at(f, f / 40.0, x + shift + nx, 50e-6 + ny));
  }
  const TrackOptions o;
  markDeposits(t, o);
  int labelled = 0;
  for (int f = 30; f < 230; ++f) labelled += t.points[f].state == "deposited" ? 1 : 0;
  EXPECT_GE(labelled, 190) << "resting points labelled deposited, of 200";
  for (int f = 0; f < 29; ++f) EXPECT_NE(t.points[f].state, "deposited") << "frame " << f;
  for (int f = 231; f < 260; ++f) EXPECT_NE(t.points[f].state, "deposited") << "frame " << f;
  const TrackStats s = analyseTracks(t, o);
  ASSERT_EQ(s.tracks.size(), 1u);
  EXPECT_EQ(s.tracks[0].state, "mobile");  // it ends moving: not retained
  // 60 moving steps at 400 um/s; unlabelled, the 200 resting steps (~0.2 px/frame of
  // noise, ~80 um/s) would pull the mean to about 150 um/s.
  EXPECT_NEAR(static_cast<double>(s.steps.size()), 60.0, 10.0);
  EXPECT_NEAR(s.mean_speed, 400e-6, 40e-6);
}

// A slow but steady creep (0.02 px/frame, 8 um/s) for 200 frames under the same noise is motion.
TEST(Deposit, SlowCreepInsideATrackIsNotARest) {
  std::mt19937_64 rng(6);
  std::normal_distribution<double> noise(0.0, 1.5e-6);
  Tracks t;
  double x = 100e-6;
  for (int f = 0; f < 260; ++f) {
    const bool creeping = f >= 30 && f < 230;
    if (f > 0) x += creeping ? 0.2e-6 : 10e-6;
    const double nx = creeping ? noise(rng) : 0.0;
    const double ny = creeping ? noise(rng) : 0.0;
    t.points.push_back(at(f, f / 40.0, x + nx, 50e-6 + ny));
  }
  markDeposits(t, TrackOptions{});
  for (const auto& p : t.points) EXPECT_NE(p.state, "deposited") << "frame " << p.frame;
}

}  // namespace
}  // namespace mmval::tracking
