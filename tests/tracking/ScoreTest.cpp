// Tracking scores (Score.hpp) on tracks whose scores follow from their definition.
#include <cmath>

#include <gtest/gtest.h>

#include "mmval/tracking/Score.hpp"

namespace mmval::tracking {
namespace {

TEST(Score, PerfectAndShiftedTracks) {
  Tracks t;
  for (int p = 0; p < 3; ++p)
    for (int f = 0; f < 10; ++f) {
      TrackPoint q;
      q.frame = f;
      q.particle = p;
      q.x_px = 10 + 3 * f;
      q.y_px = 10 + 20 * p;
      t.points.push_back(q);
    }
  const Scores same = scoreTracks(t, t);
  EXPECT_DOUBLE_EQ(same.alpha, 1.0);
  EXPECT_DOUBLE_EQ(same.jaccard_points, 1.0);
  EXPECT_DOUBLE_EQ(same.jaccard_tracks, 1.0);
  Tracks shifted = t;
  for (auto& p : shifted.points) p.x_px += 1.0;  // 1 px off everywhere, gate 5: alpha = 1 - 1/5
  const Scores s = scoreTracks(t, shifted);
  EXPECT_NEAR(s.alpha, 0.8, 1e-12);
  EXPECT_NEAR(s.rmse_px, 1.0, 1e-12);
  EXPECT_DOUBLE_EQ(s.jaccard_points, 1.0);
  Tracks half = t;
  std::erase_if(half.points, [](const TrackPoint& p) { return p.particle == 2; });
  const Scores h = scoreTracks(t, half);
  EXPECT_NEAR(h.jaccard_points, 20.0 / 30.0, 1e-12);
  EXPECT_NEAR(h.jaccard_tracks, 2.0 / 3.0, 1e-12);
}

TEST(Score, ASwapIsAGrossErrorNotALocalisationError) {
  // Two particles 4 px apart, tracked 0.3 px off in x; for frames 3-5 the two estimated
  // tracks follow each other's particle (a swap). Pairing stays identity (a swap costs
  // 3 x 4.01 px per track, the other pairing 7 x 4.01), so 14 points are 0.3 px off and
  // 6 are hypot(0.3, 4) off: the challenge's RMSE takes both, the localisation RMSE the 14.
  Tracks t, est;
  for (int p = 0; p < 2; ++p)
    for (int f = 0; f < 10; ++f) {
      TrackPoint q;
      q.frame = f;
      q.particle = p;
      q.x_px = 10 + 2 * f;
      q.y_px = 10 + 4 * p;
      t.points.push_back(q);
      const bool swapped = f >= 3 && f <= 5;
      q.x_px += 0.3;
      q.y_px = 10 + 4 * (swapped ? 1 - p : p);
      est.points.push_back(q);
    }
  const Scores s = scoreTracks(t, est);
  const double far2 = 0.3 * 0.3 + 16;
  EXPECT_EQ(s.tp, 20);
  EXPECT_EQ(s.gross_points, 6);
  EXPECT_NEAR(s.rmse_px, std::sqrt((14 * 0.09 + 6 * far2) / 20), 1e-12);
  EXPECT_NEAR(s.rmse_localisation_px, 0.3, 1e-12);
  EXPECT_EQ(s.paired_tracks, 2);
}

}  // namespace
}  // namespace mmval::tracking
