// Retention by one rule on both files (mmval/compare/Retention.hpp), on hand-made
// tracks whose answer is known by construction: crawlers, fragments of one
// particle, files built to push the fraction past 1, and a 3-of-10 scene.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "mmval/compare/Compare.hpp"
#include "mmval/compare/Retention.hpp"
#include "TrackPoints.hpp"

namespace mmval::compare {
namespace {

using test_support::pt;

constexpr double kDt = 0.025;  // s, 40 fps as the micromodel scene
constexpr double kUm = 1e-6;

/// Position (m) of a particle at time t (s).
using Path = std::function<cv::Point2d(double)>;

/// Rows of particle `id` from frame f0 to f1 inclusive along `path`, with Gaussian
/// position noise of `noise` m per axis (seeded), each labelled `state`.
void addTrack(Tracks& t, std::int64_t id, int f0, int f1, const Path& path, double noise = 0, unsigned seed = 1, const std::string& state = "") {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int f = f0; f <= f1; ++f) {
    const cv::Point2d p = path(f * kDt);
    TrackPoint q = pt(f, id, f * kDt, p.x + noise * n(rng), p.y + noise * n(rng));
    q.state = state;
    t.points.push_back(q);
  }
}

void sortRows(Tracks& t) {
  std::stable_sort(t.points.begin(), t.points.end(), [](const TrackPoint& a, const TrackPoint& b) {
    return a.particle != b.particle ? a.particle < b.particle : a.frame < b.frame;
  });
}

/// Enters at the left edge at t = 0.5 s, crosses at 400 um/s to x = 800 um, then crawls
/// along a grain wall at `crawl` (m/s) until the record ends.
Path wallCrawler(double crawl, double y) {
  return [=](double t) {
    const double t_arrive = 0.5 + 800e-6 / 400e-6;
    if (t < 0.5) return cv::Point2d(0, y);
    if (t < t_arrive) return cv::Point2d(400e-6 * (t - 0.5), y);
    return cv::Point2d(800e-6 + crawl * (t - t_arrive), y);
  };
}

/// A 2000 x 1500 um view, the micromodel scene's window.
RetentionOptions sceneOptions() {
  RetentionOptions o;
  o.view = cv::Rect2d(0, 0, 2000 * kUm, 1500 * kUm);
  return o;
}

/// One stationary bystander, always in view, so that every file holds the record's full
/// time span [0, 30] s whatever its other tracks do.
void addBystander(Tracks& t, std::int64_t id) {
  addTrack(t, id, 0, 1200, [](double) { return cv::Point2d(1000e-6, 1400e-6); });
}

TEST(Retention, WallCrawlerCountsTheSameOnBothSides) {
  // The particle that made the pipeline check fail: it crawls along a wall at 2 um/s.
  // Simulated: exact positions, no label. Tracked: 0.07 px (0.7 um at 10 um/px) of
  // localisation noise, and the tracker's label "deposited" on its last 200 rows, as
  // its own rule had it. 2 um/s is four times the rest speed (1 um over 2 s), so it is
  // moving on both sides; 0.2 um/s is below it, so at rest on both sides.
  for (const double crawl : {2.0 * kUm, 0.2 * kUm}) {
    Tracks sim, trk;
    addTrack(sim, 1, 20, 1200, wallCrawler(crawl, 700 * kUm));
    addBystander(sim, 9);
    addTrack(trk, 1, 20, 1000, wallCrawler(crawl, 700 * kUm), 0.7 * kUm, 7);
    addTrack(trk, 1, 1001, 1200, wallCrawler(crawl, 700 * kUm), 0.7 * kUm, 8, "deposited");
    addBystander(trk, 9);
    sortRows(sim);
    sortRows(trk);
    const RetentionCount s = countRetention(sim, sceneOptions()), e = countRetention(trk, sceneOptions());
    const bool slow = crawl < 0.5 * kUm;
    EXPECT_EQ(s.entered, 1) << crawl;
    EXPECT_EQ(e.entered, 1) << crawl;
    EXPECT_EQ(s.retained, slow ? 1 : 0) << crawl;
    EXPECT_EQ(e.retained, slow ? 1 : 0) << crawl;
    EXPECT_EQ(e.labelled_deposited, 1);  // the label is counted apart and decides nothing
  }
  // The numbers behind the verdicts. Exact positions: the drift of a steady crawl is the
  // crawl speed itself (both medians sit on the line), to round-off.
  std::vector<TrackPoint> exact, noisy;
  Tracks a, b;
  addTrack(a, 1, 20, 1200, wallCrawler(2 * kUm, 700 * kUm));
  addTrack(b, 1, 20, 1200, wallCrawler(2 * kUm, 700 * kUm), 0.7 * kUm, 7);
  const tracking::TrackOptions o;
  const RestVerdict va = restAtEnd(a.points, 30.0, kDt, o), vb = restAtEnd(b.points, 30.0, kDt, o);
  EXPECT_NEAR(va.drift_speed, 2 * kUm, 1e-9 * kUm);
  EXPECT_NEAR(va.noise, 0.0, 1e-12 * kUm);  // a steady crawl has no second differences
  EXPECT_NEAR(va.threshold, 0.5 * kUm, 1e-9 * kUm);  // the rest speed, 1 um over 2 s
  // Noisy: the noise estimate from the window's 80 rows (158 second differences over
  // both axes) has a relative standard error of about 10 %; 25 % is 2.5 of them. The drift's standard error is
  // 1.2533 x 0.7 um x sqrt(2/26) / 1.33 s = 0.18 um/s per axis; 0.8 um/s is 4.4 of them.
  EXPECT_NEAR(vb.noise, 0.7 * kUm, 0.25 * 0.7 * kUm);
  EXPECT_NEAR(vb.drift_speed, 2 * kUm, 0.8 * kUm);
  EXPECT_NEAR(vb.threshold, 0.5 * kUm + 3 * 0.18 * kUm, 0.25 * 3 * 0.18 * kUm);
}

TEST(Retention, SplitTrackIsOneParticleEnteredAndRetainedOnce) {
  // One particle enters at the left edge, is lost for 0.2 s in the middle of the view
  // (a passer hid it) and found again under a new id, then stops at x = 1200 um at
  // t = 20 s and rests there to the end. The second track begins inside the view, mid-record.
  const Path path = [](double t) { return cv::Point2d(std::min(60e-6 * t, 1200e-6), 600e-6); };
  Tracks t;
  addTrack(t, 11, 0, 280, path);    // 0 .. 7 s, x 0 .. 420 um
  addTrack(t, 12, 288, 1200, path); // 7.2 .. 30 s
  addBystander(t, 99);
  sortRows(t);
  const RetentionCount c = countRetention(t, sceneOptions());
  EXPECT_EQ(c.entered, 1);
  EXPECT_EQ(c.retained, 1);
  EXPECT_EQ(c.continued, 1);
  EXPECT_EQ(c.orphans, 0);
  EXPECT_DOUBLE_EQ(c.fraction, 1.0);
  // It came to rest at t = 20 s: the stop time is the first row within stuck_distance
  // (1 um, exact positions: no noise) of its resting place, 19.99 s, to a frame.
  ASSERT_EQ(c.stop_times.size(), 1u);
  EXPECT_NEAR(c.stop_times[0], 20.0, kDt);

  // Reversed roles: it rests 3 s (the tracker labels the rest deposited), is lost, and the
  // new track carries it away out of view. The chain's last track decides: not retained.
  const Path leaves = [](double t) {
    return cv::Point2d(t < 10 ? 80e-6 * t : (t < 13 ? 800e-6 : 800e-6 + 150e-6 * (t - 13)), 600e-6);
  };
  Tracks u;
  addTrack(u, 21, 0, 400, leaves);                 // to 10 s, at rest from 10 s
  addTrack(u, 21, 401, 519, leaves, 0, 1, "deposited");  // rest to 12.975 s
  addTrack(u, 22, 528, 1000, leaves);              // 13.2 s on, moving away
  addBystander(u, 99);
  sortRows(u);
  const RetentionCount d = countRetention(u, sceneOptions());
  EXPECT_EQ(d.entered, 1);
  EXPECT_EQ(d.continued, 1);
  EXPECT_EQ(d.retained, 0);

  // At rest from 20 s, the track broken at 29 s (a neighbour came by) and resumed for the
  // last 0.8 s, shorter than the 2 s window: judged on the chain's rows, it is at rest.
  Tracks w;
  addTrack(w, 31, 0, 1160, path);     // to 29 s
  addTrack(w, 32, 1168, 1200, path);  // 29.2 .. 30 s
  addBystander(w, 99);
  sortRows(w);
  const RetentionCount e = countRetention(w, sceneOptions());
  EXPECT_EQ(e.entered, 1);
  EXPECT_EQ(e.continued, 1);
  EXPECT_EQ(e.retained, 1);
}

TEST(Retention, FractionCannotExceedOne) {
  // A file built to inflate retained over entered: one particle enters and keeps moving;
  // twenty tracks begin at rest deep inside the view mid-record with no track ending near
  // them (a deposit cluster the tracker picked up late): they continue nothing and
  // entered nothing, so they are orphans, reported and never counted.
  Tracks t;
  addTrack(t, 1, 0, 1200, [](double s) { return cv::Point2d(60e-6 * s, 300e-6); });
  for (int k = 0; k < 20; ++k) {
    const double x = 500e-6 + 40e-6 * k;
    addTrack(t, 100 + k, 400, 1200, [=](double s) { return cv::Point2d(x + (s < 11 ? 30e-6 * (s - 10) : 30e-6), 900e-6); });
  }
  sortRows(t);
  const RetentionCount c = countRetention(t, sceneOptions());
  EXPECT_EQ(c.entered, 1);
  EXPECT_EQ(c.retained, 0);
  EXPECT_EQ(c.orphans, 20);
  EXPECT_EQ(c.orphans_at_rest, 20);
  EXPECT_DOUBLE_EQ(c.fraction, 0.0);

  // Random files of particles broken into fragments at random, some resting at the end:
  // whatever the linking makes of them, retained <= entered, and every point of the
  // series over time is at most 1.
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> u(0, 1);
  for (int trial = 0; trial < 20; ++trial) {
    Tracks r;
    std::int64_t id = 1;
    for (int p = 0; p < 15; ++p) {
      const double y = 50e-6 + 95e-6 * p, v = 40e-6 + 25e-6 * u(rng), stop = 5 + 25 * u(rng);
      const Path path = [=](double s) { return cv::Point2d(v * std::min(s, stop), y); };
      int f = static_cast<int>(40 * 8 * u(rng));
      while (f < 1200) {
        const int len = 3 + static_cast<int>(400 * u(rng));
        addTrack(r, id, f, std::min(1200, f + len), path, 0.5e-6, static_cast<unsigned>(id));
        ++id;
        f += len + 1 + static_cast<int>(30 * u(rng));
      }
    }
    sortRows(r);
    const RetentionCount c2 = countRetention(r, sceneOptions());
    EXPECT_LE(c2.retained, c2.entered) << trial;
    EXPECT_LE(c2.fraction, 1.0) << trial;
    std::vector<double> times;
    for (int i = 0; i <= 30; ++i) times.push_back(i);
    for (double f : retentionOverTime(c2, times).fraction) {
      if (!std::isnan(f)) {
        EXPECT_LE(f, 1.0) << trial;
      }
    }
  }
}

/// Ten particles enter at the left edge one second apart and cross the view at 100 um/s;
/// those in `stopping` stop at t = 15 s. Simulated style: a stopped particle's trajectory
/// ends with one row labelled deposited where it attached. Tracked style: its rows go on,
/// at rest, to the end, with 0.7 um of noise.
Tracks tenParticles(const std::vector<int>& stopping, bool tracked) {
  Tracks t;
  for (int p = 0; p < 10; ++p) {
    const double t0 = p;
    const bool stops = std::find(stopping.begin(), stopping.end(), p) != stopping.end();
    const Path path = [=](double s) { return cv::Point2d(100e-6 * (std::min(s, stops ? 15.0 : 1e9) - t0), 100e-6 + 130e-6 * p); };
    const int f0 = static_cast<int>(std::lround(t0 / kDt));
    const int f_stop = static_cast<int>(std::lround(15.0 / kDt));
    if (stops && !tracked) {
      addTrack(t, p, f0, f_stop - 1, path);
      addTrack(t, p, f_stop, f_stop, path, 0, 1, "deposited");
    } else {
      addTrack(t, p, f0, 1200, path, tracked ? 0.7e-6 : 0.0, 100 + p);
    }
  }
  sortRows(t);
  return t;
}

TEST(Retention, ThreeOfTenStoppedIsThreeTenthsOnBothSides) {
  const std::vector<int> stopping{2, 5, 7};
  const RetentionCount s = countRetention(tenParticles(stopping, false), sceneOptions());
  const RetentionCount e = countRetention(tenParticles(stopping, true), sceneOptions());
  for (const auto* c : {&s, &e}) {
    EXPECT_EQ(c->entered, 10);
    EXPECT_EQ(c->retained, 3);
    EXPECT_DOUBLE_EQ(c->fraction, 0.3);
    EXPECT_EQ(c->orphans, 0);
  }
  EXPECT_EQ(s.labelled_deposited, 3);  // the engine's attachments, counted apart
  // Through the comparator: the same 0.3 on both sides, error 0 (round-off), and the
  // engine's label reported as its own number.
  CompareOptions o;
  const Comparison c = compareTracks(tenParticles(stopping, true), tenParticles(stopping, false), o);
  const auto it = std::find_if(c.metrics.begin(), c.metrics.end(), [](const MetricResult& m) { return m.name == "retention_fraction"; });
  ASSERT_NE(it, c.metrics.end());
  EXPECT_NEAR(it->value, 0.3, 1e-12);
  ASSERT_TRUE(it->reference.has_value());
  EXPECT_NEAR(it->reference->value, 0.3, 1e-12);
  EXPECT_TRUE(*it->pass);
  const auto lab = std::find_if(c.metrics.begin(), c.metrics.end(), [](const MetricResult& m) { return m.name == "retention_simulation_labelled"; });
  ASSERT_NE(lab, c.metrics.end());
  EXPECT_NEAR(lab->value, 0.3, 1e-12);
}

TEST(Retention, DepositInTheLastWindowIsNotYetARestOnEitherSide) {
  // Attached at 29 s: 1 s before the end of a 30 s record, less than the 2 s window. The
  // simulated trajectory (one deposited row, held to the end) and the tracked one (rows
  // at rest to the end) both show motion in the window's first third.
  const Path path = [](double s) { return cv::Point2d(60e-6 * std::min(s, 29.0), 700e-6); };
  Tracks sim, trk;
  addTrack(sim, 1, 0, 1159, path);
  addTrack(sim, 1, 1160, 1160, path, 0, 1, "deposited");
  addBystander(sim, 9);
  addTrack(trk, 1, 0, 1200, path);
  addBystander(trk, 9);
  sortRows(sim);
  sortRows(trk);
  const RetentionCount s = countRetention(sim, sceneOptions()), e = countRetention(trk, sceneOptions());
  EXPECT_EQ(s.retained, 0);
  EXPECT_EQ(e.retained, 0);
  EXPECT_EQ(s.labelled_deposited, 1);
}

}  // namespace
}  // namespace mmval::compare
