// The comparator (Compare.hpp), the track metrics it builds on and the tracks
// CSV reader's errors, against hand-computed values; the two-sample statistics it uses are tested in
// tests/tracking/StatisticsTest.cpp.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <vector>

#include "mmval/compare/Compare.hpp"
#include "mmval/tracking/Statistics.hpp"
#include "TrackPoints.hpp"
#include "mmval/core/Error.hpp"

#include "../TestScratch.hpp"

namespace mmval::compare {
namespace {

using test_support::pt;

using namespace mmval::tracking;

/// Particle 1 moves at 10 um/s along x for 10 s, then stops for 5 s;
/// particle 2 never moves (stuck to the glass); particle 3 moves at 20 um/s along y.
Tracks scene(double speed_scale = 1.0) {
  Tracks t;
  for (int f = 0; f <= 15; ++f) {
    const double time = f;
    const double x1 = std::min(f, 10) * 10e-6 * speed_scale;
    t.points.push_back(pt(f, 1, time, 100e-6 + x1, 50e-6));
    t.points.push_back(pt(f, 2, time, 20e-6, 20e-6));
    t.points.push_back(pt(f, 3, time, 60e-6, 10e-6 + f * 20e-6 * speed_scale));
  }
  std::stable_sort(t.points.begin(), t.points.end(), [](const TrackPoint& a, const TrackPoint& b) {
    return a.particle != b.particle ? a.particle < b.particle : a.frame < b.frame;
  });
  return t;
}

TEST(TrackMetrics, ImmobileExcludedRetainedCountedSpeedsExact) {
  const TrackStats s = analyseTracks(scene(), TrackOptions{});
  EXPECT_EQ(s.particles, 3);
  EXPECT_EQ(s.immobile, 1);
  EXPECT_EQ(s.mobile, 2);
  EXPECT_EQ(s.retained, 1);  // particle 1 stopped for the last 5 s (> 2 s window)
  EXPECT_DOUBLE_EQ(s.retained_fraction, 0.5);
  // 30 steps: particle 1 has 10 at 10 um/s and 5 at 0; particle 3 has 15 at 20 um/s.
  EXPECT_EQ(s.steps.size(), 30u);
  EXPECT_NEAR(s.mean_speed, (10 * 10e-6 + 15 * 20e-6) / 30, 1e-15);
  EXPECT_NEAR(s.median_speed, 15e-6, 1e-15);  // between the 15th (10) and 16th (20) sorted speeds
}

TEST(TrackMetrics, DispersionIsThePopulationStdPerFrame) {
  Tracks t;
  // Two particles 2 um apart in x at every frame: sigma_x = 1 um, sigma_y = 0.
  for (int f = 0; f < 5; ++f) {
    t.points.push_back(pt(f, 1, f * 0.1, 0.0 + f * 5e-6, 0.0));
    t.points.push_back(pt(f, 2, f * 0.1, 2e-6 + f * 5e-6, 0.0));
  }
  std::stable_sort(t.points.begin(), t.points.end(), [](const TrackPoint& a, const TrackPoint& b) {
    return a.particle != b.particle ? a.particle < b.particle : a.frame < b.frame;
  });
  const TrackStats s = analyseTracks(t, TrackOptions{});
  EXPECT_NEAR(s.sigma_x, 1e-6, 1e-18);
  EXPECT_NEAR(s.sigma_y, 0.0, 1e-18);
}

TEST(Compare, IdenticalTracksAgreeOnEveryMetric) {
  const Comparison c = compareTracks(scene(), scene(), CompareOptions{});
  for (const auto& m : c.metrics) {
    if (m.pass) {
      EXPECT_TRUE(*m.pass) << m.name;
    }
  }
  EXPECT_DOUBLE_EQ(c.iou, 1.0);
  EXPECT_DOUBLE_EQ(c.ks_statistic, 0.0);
  EXPECT_DOUBLE_EQ(c.wasserstein, 0.0);
}

TEST(Compare, FasterSimulationFailsSpeedWithTheRightError) {
  const Comparison c = compareTracks(scene(), scene(1.5), CompareOptions{});
  const auto it = std::find_if(c.metrics.begin(), c.metrics.end(), [](const MetricResult& m) { return m.name == "mean_speed"; });
  ASSERT_NE(it, c.metrics.end());
  EXPECT_NEAR(it->error, 0.5, 1e-9);  // every moving step is 1.5 times faster
  EXPECT_FALSE(*it->pass);
  EXPECT_EQ(it->unit, "um/s");
}

TEST(Compare, WritesFilesAndReadsBackTheSchema) {
  const auto dir = mmval::test::scratch("compare-files");
  std::filesystem::remove_all(dir);
  const auto files = writeComparison(compareTracks(scene(), scene(1.2), CompareOptions{}), dir);
  EXPECT_THAT(files, ::testing::Contains("streamlines.png"));
  EXPECT_TRUE(std::filesystem::exists(dir / "metrics.json"));
  writeTracksCsv(dir / "tracks.csv", scene(), 0.5e-6);
  const Tracks back = readTracksCsv(dir / "tracks.csv");
  ASSERT_EQ(back.points.size(), scene().points.size());
  EXPECT_NEAR(back.points[5].x, scene().points[5].x, 1e-11);
  EXPECT_NEAR(back.points[5].x_px, scene().points[5].x / 0.5e-6, 1e-3);
}

/// Particle i moves along x at (base + i) um/s for 20 frames 0.1 s apart, on its own row.
Tracks constantSpeeds(int particles, double base_um_s) {
  Tracks t;
  for (int i = 0; i < particles; ++i)
    for (int f = 0; f < 20; ++f) t.points.push_back(pt(f, i, 0.1 * f, (base_um_s + i) * 1e-6 * 0.1 * f, 30e-6 * i));
  return t;
}

const MetricResult& metricNamed(const Comparison& c, const std::string& name) {
  const auto it = std::find_if(c.metrics.begin(), c.metrics.end(), [&](const MetricResult& m) { return m.name == name; });
  EXPECT_NE(it, c.metrics.end()) << name;
  return *it;
}

TEST(Compare, IdenticalSetsHaveZeroDistancesAndZeroErrors) {
  const Comparison c = compareTracks(constantSpeeds(20, 5), constantSpeeds(20, 5), CompareOptions{});
  for (const auto& m : c.metrics) {
    if (!m.pass) continue;
    EXPECT_TRUE(*m.pass) << m.name;
    if (m.tolerance != "interval") {
      EXPECT_NEAR(m.error, 0.0, 1e-12) << m.name;
    }
  }
  EXPECT_NEAR(metricNamed(c, "speed_wasserstein1").value, 0.0, 1e-12);
  EXPECT_NEAR(metricNamed(c, "speed_ks_statistic").value, 0.0, 1e-12);
  EXPECT_NEAR(metricNamed(c, "speed_ks_p_value").value, 1.0, 1e-12);
  EXPECT_NEAR(metricNamed(c, "streamline_iou").value, 1.0, 1e-12);
}

TEST(Compare, ShiftedSpeedDistributionGivesTheShiftAsWasserstein) {
  // Speeds 5..24 um/s against 8..27 um/s, 19 steps each: W1 is the 3 um/s shift;
  // the CDFs differ by at most 3 particles of 20, KS D = 0.15.
  const Comparison c = compareTracks(constantSpeeds(20, 5), constantSpeeds(20, 8), CompareOptions{});
  EXPECT_NEAR(c.wasserstein, 3e-6, 1e-12);
  EXPECT_NEAR(metricNamed(c, "speed_wasserstein1").value, 3.0, 1e-6);
  EXPECT_NEAR(c.ks_statistic, 0.15, 1e-12);
  EXPECT_NEAR(metricNamed(c, "mean_speed").value, 17.5, 1e-6);
  EXPECT_NEAR(metricNamed(c, "mean_speed").reference->value, 14.5, 1e-6);
}

/// Exact two-sided two-sample KS p-value P(D >= d) under the null for samples of m and n
/// without ties: one minus the share of the C(m + n, m) orderings whose lattice path keeps
/// |i/m - j/n| < d (Hodges 1958, Ark. Mat. 3, 469), an independent check of the asymptotic formula.
double exactKsPValue(int m, int n, double d) {
  std::vector<std::vector<double>> paths(m + 1, std::vector<double>(n + 1, 0.0));
  for (int i = 0; i <= m; ++i)
    for (int j = 0; j <= n; ++j) {
      if (std::abs(double(i) * n - double(j) * m) >= d * m * n - 1e-9) continue;
      paths[i][j] = (i == 0 && j == 0) ? 1.0 : (i > 0 ? paths[i - 1][j] : 0.0) + (j > 0 ? paths[i][j - 1] : 0.0);
    }
  double total = 1;  // C(m + n, m)
  for (int k = 1; k <= m; ++k) total = total * (n + k) / k;
  return 1 - paths[m][n] / total;
}

TEST(Compare, PerTrackKsCountsTracksNotCorrelatedSteps) {
  // Track speeds 5..24 um/s against 15..34 um/s, 19 steps a track: D = 10/20 = 0.5 both per
  // step and per track. Per step the asymptotic p-value takes 380 + 380 steps as independent
  // (n_e = 190): about 1.9e-42. Per track it has 20 + 20 samples (n_e = 10):
  // Q_KS((sqrt(10) + 0.12 + 0.11 / sqrt(10)) 0.5) = 0.00816, against the exact
  // permutation p-value 0.0123 of D = 0.5 at m = n = 20.
  const Comparison c = compareTracks(constantSpeeds(20, 5), constantSpeeds(20, 15), CompareOptions{});
  EXPECT_EQ(c.track_samples_experiment, 20);
  EXPECT_EQ(c.track_samples_simulation, 20);
  EXPECT_NEAR(metricNamed(c, "track_speed_ks_statistic").value, 0.5, 1e-12);
  EXPECT_NEAR(c.ks_statistic, 0.5, 1e-12);
  const double lambda = (std::sqrt(10.0) + 0.12 + 0.11 / std::sqrt(10.0)) * 0.5;
  double q = 0;
  for (int j = 1; j <= 100; ++j) q += 2 * ((j % 2) ? 1.0 : -1.0) * std::exp(-2.0 * j * j * lambda * lambda);
  const MetricResult& track_p = metricNamed(c, "track_speed_ks_p_value");
  EXPECT_NEAR(track_p.value, q, 1e-12 * q);
  EXPECT_NEAR(q, 0.00816168, 1e-7);
  // The asymptotic value is within a factor 2 of the exact one at 20 samples a side (Stephens' correction).
  const double exact = exactKsPValue(20, 20, 0.5);
  EXPECT_NEAR(exact, 0.0122986, 1e-6);
  EXPECT_GT(track_p.value, exact / 2);
  EXPECT_LT(track_p.value, exact * 2);
  // The per-step p-value is some forty orders of magnitude smaller for the same D.
  EXPECT_LT(metricNamed(c, "speed_ks_p_value").value, 1e-40);
  EXPECT_THAT(track_p.reason, ::testing::HasSubstr("20 and 20 moving tracks"));
  EXPECT_THAT(metricNamed(c, "speed_ks_p_value").reason, ::testing::HasSubstr("380 and 380 per-frame steps"));
}

TEST(Compare, ReferenceTracksAreNamedByWhatTheyAre) {
  // A user's file is "experiment tracks"; tracks of another run (a tracked rendering of a
  // simulation in validate's pipeline check) are named by that run, not called an experiment.
  const Comparison user = compareTracks(constantSpeeds(20, 5), constantSpeeds(20, 8), CompareOptions{});
  ASSERT_TRUE(metricNamed(user, "mean_speed").reference.has_value());
  EXPECT_EQ(metricNamed(user, "mean_speed").reference->source, "experiment tracks");
  CompareOptions o;
  o.reference_name = "tracks of run tracking-rendered-micromodel";
  const Comparison run = compareTracks(constantSpeeds(20, 5), constantSpeeds(20, 8), o);
  for (const char* name : {"mean_speed", "median_speed", "sigma_x", "sigma_y", "retention_fraction"}) {
    ASSERT_TRUE(metricNamed(run, name).reference.has_value()) << name;
    EXPECT_EQ(metricNamed(run, name).reference->source, "tracks of run tracking-rendered-micromodel") << name;
  }
  // Same numbers either way: 14.5 um/s reference, 17.5 um/s candidate.
  EXPECT_NEAR(metricNamed(run, "mean_speed").reference->value, 14.5, 1e-6);
  EXPECT_NEAR(metricNamed(run, "mean_speed").value, 17.5, 1e-6);
  for (const auto& m : run.metrics) EXPECT_THAT(m.reason, ::testing::Not(::testing::HasSubstr("experiment"))) << m.name;
}

TEST(Compare, KnownRetentionIsReportedExactly) {
  // Seven mobile particles moving 10 um/s; in the experiment three stop at t = 1 s
  // (and stay put for 1.9 s), in the simulation four do.
  auto scene7 = [](int stopping) {
    Tracks t;
    for (int p = 0; p < 7; ++p)
      for (int f = 0; f <= 29; ++f) {
        const double time = 0.1 * f;
        const double x = 10e-6 * (p < stopping ? std::min(time, 1.0) : time);
        t.points.push_back(pt(f, p, time, x, 40e-6 * p));
      }
    return t;
  };
  CompareOptions o;
  o.tracks.stuck_window = 1.0;
  const Comparison c = compareTracks(scene7(3), scene7(4), o);
  EXPECT_EQ(c.experiment.mobile, 7);
  EXPECT_EQ(c.experiment.retained, 3);
  EXPECT_EQ(c.simulation.retained, 4);
  const MetricResult& r = metricNamed(c, "retention_fraction");
  EXPECT_NEAR(r.value, 4.0 / 7.0, 1e-12);
  EXPECT_NEAR(r.reference->value, 3.0 / 7.0, 1e-12);
  EXPECT_NEAR(std::abs(r.error), 1.0 / 7.0, 1e-12);
  EXPECT_FALSE(*r.pass);  // 0.143 beyond the 0.05 absolute tolerance
  // Over time: nobody retained before t = 1 s, 3/7 from then on.
  const auto& series = c.retention_experiment;
  ASSERT_FALSE(series.t.empty());
  for (std::size_t i = 0; i < series.t.size(); ++i)
    EXPECT_NEAR(series.fraction[i], series.t[i] < 1.0 - 1e-9 ? 0.0 : 3.0 / 7.0, 1e-12) << "t = " << series.t[i];
}

TEST(TracksCsv, BadInputNamesFileLineAndColumn) {
  const auto dir = mmval::test::scratch("compare-bad-input");
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "bad1.csv") << "frame,particle,t_s,x_um\n0,1,0.0,5\n";
  try {
    readTracksCsv(dir / "bad1.csv");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_THAT(std::string(e.what()), ::testing::HasSubstr("bad1.csv:1"));
    EXPECT_THAT(std::string(e.what()), ::testing::HasSubstr("y_um"));
  }
  std::ofstream(dir / "bad2.csv") << "frame,particle,t_s,x_um,y_um\n0,1,0.0,5,6\n1,1,0.1,abc,6\n";
  try {
    readTracksCsv(dir / "bad2.csv");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_THAT(std::string(e.what()), ::testing::HasSubstr("bad2.csv:3:4"));
    EXPECT_THAT(std::string(e.what()), ::testing::HasSubstr("x_um"));
  }
}

}  // namespace
}  // namespace mmval::compare
