// The rest rule compareTracks applies to both files (labelRests, Compare.hpp): a pair of files
// with the same motion, one labelling its rest "deposited" (as the tracker does) and one keeping
// it "mobile" (as a simulation engine does for a particle held at a wall), gives the same speed
// statistics after the rule, against values computed by hand; a file without rests is unchanged.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "mmval/compare/Compare.hpp"
#include "TrackPoints.hpp"

namespace mmval::compare {
namespace {

using test_support::pt;

constexpr double um = 1e-6;
constexpr double dt = 0.01;  // s per frame

/// Frames 0-129, 0.01 s apart. Particle 1 moves 5 um per frame along x (500 um/s) to frame 50,
/// rests at x = 250 um over frames 50-79 (0.29 s), then moves on at 500 um/s. Particle 2 moves
/// 3 um per frame along y (300 um/s) all along, 300 um away. `tracker`: the rest's points are
/// labelled deposited and sit still; otherwise they stay mobile and the odd frames 51-77 sit
/// 0.2 um off in y (a particle jittering against a wall: 28 steps of 0.2 um, 20 um/s).
Tracks pair(bool tracker) {
  Tracks t;
  for (int f = 0; f <= 129; ++f) {
    const double x = f <= 79 ? 5.0 * std::min(f, 50) : 250.0 + 5.0 * (f - 79);
    const bool rest = f >= 50 && f <= 79;
    const double y = !tracker && rest && f <= 77 && f % 2 == 1 ? 0.2 : 0.0;
    TrackPoint p = pt(f, 1, dt * f, x * um, (100.0 + y) * um);
    p.state = tracker && rest ? "deposited" : "mobile";
    t.points.push_back(p);
  }
  for (int f = 0; f <= 129; ++f) {
    TrackPoint p = pt(f, 2, dt * f, 400 * um, (400.0 + 3.0 * f) * um);
    p.state = "mobile";
    t.points.push_back(p);
  }
  return t;
}

const MetricResult& named(const Comparison& c, const std::string& name) {
  const auto it = std::find_if(c.metrics.begin(), c.metrics.end(), [&](const MetricResult& m) { return m.name == name; });
  EXPECT_NE(it, c.metrics.end()) << name;
  return *it;
}

CompareOptions rule(double window) {
  CompareOptions o;
  o.rest.window = window;
  o.rest.distance = 1 * um;
  o.tracks.stuck_window = 0.2;
  o.speed_tolerance = 0.10;
  return o;
}

TEST(CompareRestRule, OneRuleOnBothFilesGivesTheSameSpeeds) {
  // By hand, after the rule (window 0.2 s, 1 um): the 30 points of frames 50-79 rest on both
  // sides (the windows inside them move < 1 um; a window reaching a moving point has that
  // point 5 um from its median, beyond r = 1 um + 3 sigma = 2.7 um), so both keep particle 1's
  // 100 steps at 500 um/s and particle 2's 129 at 300 um/s: mean (100 x 500 + 129 x 300) / 229
  // = 387.336 um/s, median 300 um/s (the 115th of 229 sorted), W1 0.
  const Comparison c = compareTracks(pair(true), pair(false), rule(0.2));
  EXPECT_EQ(c.rest_experiment.at_rest, 30u);
  EXPECT_EQ(c.rest_simulation.at_rest, 30u);
  EXPECT_EQ(c.rest_experiment.labelled_in_file, 30u);
  EXPECT_EQ(c.rest_simulation.labelled_in_file, 0u);
  EXPECT_EQ(c.rest_simulation.points, 260u);
  EXPECT_EQ(c.experiment.steps.size(), 229u);
  EXPECT_EQ(c.simulation.steps.size(), 229u);
  const double mean = (100 * 500.0 + 129 * 300.0) / 229;
  EXPECT_NEAR(named(c, "mean_speed").value, mean, 1e-9);
  EXPECT_NEAR(c.experiment.mean_speed / um, mean, 1e-9);
  EXPECT_NEAR(c.simulation.median_speed / um, 300.0, 1e-9);
  EXPECT_NEAR(c.experiment.median_speed / um, 300.0, 1e-9);
  EXPECT_NEAR(c.wasserstein / um, 0.0, 1e-9);
  EXPECT_NEAR(c.simulation.sigma_x, c.experiment.sigma_x, 1e-15);
  EXPECT_TRUE(*named(c, "mean_speed").pass);
  EXPECT_TRUE(*named(c, "median_speed").pass);
}

TEST(CompareRestRule, WithoutTheRuleTheUnlabelledRestCountsAsMotion) {
  // Rule off (window 0), each file's labels: the simulated side adds the rest's 29 steps (28 at
  // 20 um/s, one at 0): mean (50000 + 38700 + 560) / 258 = 345.969 um/s against 387.336, -10.7 %.
  const Comparison c = compareTracks(pair(true), pair(false), rule(0.0));
  EXPECT_EQ(c.simulation.steps.size(), 258u);
  const double sim = (100 * 500.0 + 129 * 300.0 + 28 * 20.0) / 258, exp = (100 * 500.0 + 129 * 300.0) / 229;
  EXPECT_NEAR(named(c, "mean_speed").value, sim, 1e-9);
  EXPECT_NEAR(named(c, "mean_speed").error, (sim - exp) / exp, 1e-12);
  EXPECT_FALSE(*named(c, "mean_speed").pass);  // tolerance 10 %
}

TEST(CompareRestRule, FileWithoutRestsIsUnchanged) {
  // Both particles move all along: nothing rests, every label stays, and the comparison with the
  // rule equals the one without: mean (129 x 500 + 129 x 300) / 258 = 400 um/s.
  Tracks t;
  for (int p = 1; p <= 2; ++p)
    for (int f = 0; f <= 129; ++f) {
      TrackPoint q = pt(f, p, dt * f, (p == 1 ? 5.0 * f : 400.0) * um, (p == 1 ? 100.0 : 400.0 + 3.0 * f) * um);
      q.state = "mobile";
      t.points.push_back(q);
    }
  Tracks relabelled = t;
  const RestCount n = labelRests(relabelled, {0.2, 1 * um});
  EXPECT_EQ(n.at_rest, 0u);
  for (std::size_t k = 0; k < t.points.size(); ++k) EXPECT_EQ(relabelled.points[k].state, t.points[k].state) << k;
  const Comparison on = compareTracks(t, t, rule(0.2)), off = compareTracks(t, t, rule(0.0));
  EXPECT_DOUBLE_EQ(on.simulation.mean_speed, off.simulation.mean_speed);
  EXPECT_NEAR(on.simulation.mean_speed / um, 400.0, 1e-9);
  EXPECT_EQ(on.simulation.steps.size(), 258u);
}

TEST(CompareRestRule, NoisyRestIsARestAndAMovingDepositLabelIsNot) {
  // A tracker's rest: x alternates 500 +- 0.6 um (moves 1.2 um > 1 um between frames), so a
  // window is at rest by the noise branch: sigma = sqrt(1.2^2 / 4) = 0.6 um, r = 1 + 3 x 0.6 =
  // 2.8 um, every point within 1.2 um of the median. Its 30 points rest; the moving points next
  // to it, 9.4 um or more from a window's median, do not (r <= 6.2 um for a window holding two
  // of them; three are more than 10 % of its 21 points). A row labelled deposited where the
  // particle moves 10 um per frame is relabelled mobile.
  Tracks t;
  for (int f = 0; f <= 129; ++f) {
    const bool rest = f >= 50 && f <= 79;
    const double x = f < 50 ? 10.0 * f : (rest ? 500.0 + (f % 2 == 0 ? 0.6 : -0.6) : 500.0 + 10.0 * (f - 79));
    TrackPoint p = pt(f, 1, dt * f, x * um, 100 * um);
    p.state = f == 20 ? "deposited" : "mobile";
    t.points.push_back(p);
  }
  const RestCount n = labelRests(t, {0.2, 1 * um});
  EXPECT_EQ(n.labelled_in_file, 1u);
  EXPECT_EQ(n.at_rest, 30u);
  for (int f = 0; f <= 129; ++f) EXPECT_EQ(t.points[f].state, f >= 50 && f <= 79 ? "deposited" : "mobile") << f;
}

}  // namespace
}  // namespace mmval::compare
