// Deposited particles: particles that move and then stop are
// counted as retained from the time they stopped, whether they stop late (still
// foreground after background removal) or early enough to become part of the
// temporal median background (then the tracker joins the particle it finds in the
// background to the track that brought it there). Particles stuck from the first
// frame stay immobile. Truth comes from the rendered scenes. Seconds (integration).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <random>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>

#include "mmval/tracking/Pipeline.hpp"
#include "mmval/tracking/TrackMetrics.hpp"
#include "mmval/tracking/Synth.hpp"

namespace mmval::tracking {
namespace {

namespace fs = std::filesystem;

fs::path outputDir(const char* name) {
  const fs::path dir = fs::path(MMVAL_BINARY_DIR) / "test-output" / name;
  fs::remove_all(dir);
  fs::create_directories(dir / "frames");
  return dir;
}

TrackPoint at(std::int64_t frame, std::int64_t particle, double t, double x_m, double y_m) {
  TrackPoint p;
  p.frame = frame;
  p.particle = particle;
  p.t = t;
  p.x = x_m;
  p.y = y_m;
  p.x_px = x_m * 1e5;
  p.y_px = y_m * 1e5;
  return p;
}

// 10 um pixels, as the rendered micromodel: localisation noise of 0.15 px is 1.5 um,
// above the default stuck_distance of 1 um. A particle at rest under that noise is
// stopped; one creeping at 0.05 px/frame (5 um/s) is not.
TEST(Deposit, RestUnderLocalisationNoiseIsStoppedSlowDriftIsNot) {
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, 1.5e-6);
  Tracks resting, creeping;
  for (int f = 0; f < 80; ++f) {
    const double t = f / 10.0;
    const double x = std::min(f, 30) * 10e-6;  // 1 px/frame for 3 s, then at rest for 5 s
    resting.points.push_back(at(f, 1, t, 100e-6 + x + (f >= 30 ? noise(rng) : 0.0), 50e-6 + (f >= 30 ? noise(rng) : 0.0)));
    creeping.points.push_back(at(f, 1, t, 100e-6 + f * 0.5e-6 + noise(rng), 50e-6 + noise(rng)));
  }
  const TrackOptions o;
  EXPECT_TRUE(isStopped(resting.points, 0, resting.points.size(), o));
  EXPECT_FALSE(isStopped(creeping.points, 0, creeping.points.size(), o));
  // It stopped at frame 30: the resting stretch starts there, within a frame.
  const std::size_t k = stopIndex(resting.points, 0, resting.points.size(), o);
  EXPECT_NEAR(static_cast<double>(k), 30.0, 1.0);
  // Labelled from there on; its resting steps leave the velocity statistics.
  markDeposits(resting, o);
  EXPECT_EQ(resting.points.back().state, "deposited");
  EXPECT_NE(resting.points[20].state, "deposited");
  const TrackStats s = analyseTracks(resting, o);
  ASSERT_EQ(s.tracks.size(), 1u);
  EXPECT_EQ(s.tracks[0].state, "deposited");
  EXPECT_NEAR(s.tracks[0].stop_time, 3.0, 0.1 + 1e-12);
  EXPECT_NEAR(static_cast<double>(s.steps.size()), 30.0, 1.0);
  EXPECT_NEAR(s.mean_speed, 100e-6, 5e-6);  // 1 px/frame at 10 um/px and 10 fps
}

// A particle the tracker loses mid-video and finds again is two tracks; only the first
// entered the view, so the fraction retained is 1 of 2 particles, not 1 of 3 tracks.
TEST(Deposit, TracksBeginningInsideLaterAreNotNewParticles) {
  Tracks t;
  for (int f = 0; f < 100; ++f) {
    const double time = f / 10.0;
    // Particle 0: enters at the left edge at frame 40, lost at frame 60.
    if (f >= 40 && f < 60) t.points.push_back(at(f, 0, time, (f - 40) * 10e-6, 500e-6));
    // Particle 1 continues it from frame 63, deep inside, then stops at frame 80.
    if (f >= 63) t.points.push_back(at(f, 1, time, (std::min(f, 80) - 40) * 10e-6, 500e-6));
    // Particle 2: present from the first frame, crosses the view.
    t.points.push_back(at(f, 2, time, 50e-6 + f * 10e-6, 100e-6));
    // Particle 3 marks the far corner of the view.
    t.points.push_back(at(f, 3, time, 1000e-6, 1000e-6));
  }
  std::stable_sort(t.points.begin(), t.points.end(), [](const TrackPoint& a, const TrackPoint& b) {
    return a.particle != b.particle ? a.particle < b.particle : a.frame < b.frame;
  });
  const TrackStats s = analyseTracks(t, TrackOptions{});
  EXPECT_EQ(s.mobile, 3);
  EXPECT_EQ(s.immobile, 1);
  EXPECT_EQ(s.entered, 2);
  EXPECT_EQ(s.retained, 1);
  EXPECT_NEAR(s.retained_fraction, 0.5, 1e-12);
}

// Twenty particles on separate lanes, 2 px/frame along x, 60 frames at 10 fps, 1 um/px.
// Six stop: three early (frames 8-16: at rest for most of the video, so in the median
// background) and three late (frames 32-38: still foreground). Three more are stuck
// from the first frame. Truth: 6 of 20 retained (0.30), 3 immobile.
TEST(Deposit, EarlyAndLateDepositsAreRetainedFromWhenTheyStopped) {
  const fs::path dir = outputDir("deposit-lanes");
  const int frames = 60, width = 220, height = 150;
  const std::map<int, int> stop_frame = {{1, 8}, {5, 12}, {9, 16}, {3, 32}, {13, 35}, {17, 38}};
  std::mt19937_64 rng(5);
  std::normal_distribution<double> noise(0.0, 0.015);
  auto lane_x = [&](int k, int f) {
    const auto it = stop_frame.find(k);
    const int moving = it == stop_frame.end() ? f : std::min(f, it->second);
    return 8.0 + (k * 13) % 40 + 0.37 * k + 2.0 * moving;
  };
  auto lane_y = [](int k) { return 8.0 + 7.0 * k + 0.21 * (k % 3); };
  for (int f = 0; f < frames; ++f) {
    cv::Mat img(height, width, CV_32F, cv::Scalar(0.8));
    auto spot = [&](double x, double y) {
      for (int yy = std::max(0, static_cast<int>(y) - 6); yy <= std::min(height - 1, static_cast<int>(y) + 6); ++yy)
        for (int xx = std::max(0, static_cast<int>(x) - 6); xx <= std::min(width - 1, static_cast<int>(x) + 6); ++xx)
          img.at<float>(yy, xx) -= static_cast<float>(0.35 * std::exp(-((xx - x) * (xx - x) + (yy - y) * (yy - y)) / (2 * 1.3 * 1.3)));
    };
    for (int k = 0; k < 20; ++k) spot(lane_x(k, f), lane_y(k));
    for (int k = 0; k < 3; ++k) spot(200.3, lane_y(3 * k) + 3.5);  // stuck from the first frame, beyond every lane's reach
    for (int y = 0; y < height; ++y)
      for (int x = 0; x < width; ++x) img.at<float>(y, x) += static_cast<float>(noise(rng));
    cv::Mat bytes;
    img.convertTo(bytes, CV_8U, 255.0);
    cv::imwrite((dir / "frames" / fmt::format("frame_{:05d}.png", f)).string(), bytes);
  }
  TrackConfig c;
  c.detect.find_stuck = true;
  c.detect.polarity = Polarity::dark;
  FrameSource source((dir / "frames").string());
  const TrackRun run = runTracker(source, c, true);
  const TrackStats s = analyseTracks(run.tracks, c.analysis);
  std::printf("lanes: %d mobile, %d entered, %d retained (%.3f, truth 0.300), %d immobile (truth 3), %d joined from the background, %d not\n",
              s.mobile, s.entered, s.retained, s.retained_fraction, s.immobile, run.deposits_joined, run.deposits_unjoined);
  EXPECT_EQ(s.immobile, 3);
  EXPECT_EQ(run.deposits_joined, 3);  // the three early ones
  EXPECT_EQ(s.mobile, 20);
  EXPECT_EQ(s.retained, 6);
  EXPECT_NEAR(s.retained_fraction, 0.30, 0.03);
  // Each deposited track is retained from the frame its particle stopped (within one).
  for (const auto& t : s.tracks) {
    if (t.state != "deposited") continue;
    const auto first = std::find_if(run.tracks.points.begin(), run.tracks.points.end(), [&](const TrackPoint& p) { return p.particle == t.particle; });
    ASSERT_NE(first, run.tracks.points.end());
    const int lane = static_cast<int>(std::lround((first->y_px - 8.0) / 7.0));
    ASSERT_TRUE(stop_frame.count(lane)) << "track " << t.particle << " on lane " << lane << " is not a deposit";
    EXPECT_NEAR(t.stop_time * 10.0, stop_frame.at(lane), 1.0 + 1e-9) << "lane " << lane;
  }
}

// writeSyntheticVideo's scene with a known deposit_fraction: the tracked fraction
// retained matches the truth's, both measured by the same analysis.
TEST(Deposit, SyntheticVideoRecoversTheTruthsRetainedFraction) {
  SynthOptions o;
  o.frames = 50;
  o.particles = 40;
  o.immobile = 4;
  o.deposit_fraction = 0.3;
  o.seed = 4;
  const fs::path dir = outputDir("deposit-synth");
  const SynthResult synth = writeSyntheticVideo(o, dir);
  TrackConfig c;
  c.detect.find_stuck = true;
  c.analysis.stuck_window = 0.5;  // the scene's deposits rest 0.5 to 2 s before the end
  FrameSource source((dir / "frames").string());
  const TrackRun run = runTracker(source, c, true);
  Tracks truth = synth.truth;
  markDeposits(truth, c.analysis);
  const TrackStats ts = analyseTracks(truth, c.analysis), ours = analyseTracks(run.tracks, c.analysis);
  std::printf("synthetic: truth %d of %d entered retained (%.3f), tracked %d of %d (%.3f); %d deposited in the truth's scene\n", ts.retained,
              ts.entered, ts.retained_fraction, ours.retained, ours.entered, ours.retained_fraction, synth.deposited);
  EXPECT_GT(ts.retained, 5);
  EXPECT_NEAR(ours.retained_fraction, ts.retained_fraction, 0.03);
  EXPECT_EQ(ours.immobile, 4);
}

// Rests in the middle of a track (deposits, and speeds per region): a
// deposit whose track a passing particle takes over rests for hundreds of frames and
// then moves on. Those resting steps are localisation noise, not motion, and leave the
// velocity statistics as a trailing rest's do.

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
    t.points.push_back(at(f, 1, f / 40.0, x + shift + nx, 50e-6 + ny));
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
    t.points.push_back(at(f, 1, f / 40.0, x + nx, 50e-6 + ny));
  }
  markDeposits(t, TrackOptions{});
  for (const auto& p : t.points) EXPECT_NE(p.state, "deposited") << "frame " << p.frame;
}

}  // namespace
}  // namespace mmval::tracking
