// The Brownian analysis as a user reaches it: the tracking-video case keys that
// configure it (Kinds.hpp: trackerConfig, runTrackingVideo) and the tracker end
// to end on small synthetic videos (Pipeline.hpp), flow told from diffusion and
// D against the rendered one.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "mmval/core/Case.hpp"
#include "mmval/core/CaseKind.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/tracking/Brownian.hpp"
#include "mmval/tracking/Kinds.hpp"
#include "mmval/tracking/Pipeline.hpp"
#include "mmval/tracking/Synth.hpp"
#include "../InputErrorMessage.hpp"

namespace mmval::tracking {
namespace {

namespace fs = std::filesystem;

constexpr double kUm2 = 1e-12;

fs::path render(const char* name, const SynthOptions& o) {
  const fs::path dir = fs::path(MMVAL_BINARY_DIR) / "test-output" / name;
  fs::remove_all(dir);
  writeSyntheticVideo(o, dir);
  return dir;
}

nlohmann::json summaryOf(const fs::path& dir) {
  std::ifstream in(dir / "summary.json");
  return nlohmann::json::parse(in);
}

CaseKindRegistry& registry() {
  static CaseKindRegistry r = [] {
    CaseKindRegistry reg;
    registerTrackingKinds(reg);
    return reg;
  }();
  return r;
}

/// A tracking-video case over three blank frames with `extra` TOML appended.
Case blankCase(const std::string& name, const std::string& extra) {
  const fs::path d = fs::path(MMVAL_BINARY_DIR) / "test-output" / name;
  fs::remove_all(d);
  fs::create_directories(d);
  for (int k = 0; k < 3; ++k) cv::imwrite((d / ("f" + std::to_string(k) + ".png")).string(), cv::Mat(40, 40, CV_8U, cv::Scalar(128)));
  return Case::parse("[case]\nname = \"t\"\nkind = \"tracking-video\"\n[inputs]\nvideo = \"" + d.string() +
                         "\"\nframe_rate = \"10 Hz\"\npixel_size = \"1 um\"\n" + extra,
                     d / "case.toml", registry());
}

std::string inputErrorOf(const std::function<void()>& f) { return mmval::test::inputErrorMessage(f); }

TEST(BrownianKeys, CaseKeysReachTheTracker) {
  const Case c = blankCase("brownian-keys", "[analysis]\nmotion = \"brownian\"\nexposure = \"20 ms\"\nbrownian_min_points = 25\n"
                                            "msd_lags = 4\nimmobile_level = 0.001\n[link]\npredict = \"velocity\"\n");
  const TrackConfig t = trackerConfig(c);
  EXPECT_EQ(t.analysis.motion, MotionModel::brownian);
  EXPECT_NEAR(t.analysis.brownian.exposure, 0.02, 1e-15);
  EXPECT_EQ(t.analysis.brownian.min_points, 25);
  EXPECT_EQ(t.analysis.brownian.max_lag, 4);
  EXPECT_NEAR(t.analysis.brownian.immobile_level, 0.001, 1e-15);
  EXPECT_EQ(t.link.predict, Prediction::velocity);
  // Defaults: auto and auto.
  const TrackConfig d = trackerConfig(blankCase("brownian-defaults", ""));
  EXPECT_EQ(d.analysis.motion, MotionModel::automatic);
  EXPECT_EQ(d.link.predict, Prediction::automatic);
}

TEST(BrownianKeys, ExposureLongerThanAFrameIsNamed) {
  const Case c = blankCase("brownian-exposure", "[analysis]\nexposure = \"0.2 s\"\n");
  const std::string msg = inputErrorOf([&] { runTrackingVideo(c, {c.file().parent_path() / "out", true}); });
  EXPECT_NE(msg.find("analysis.exposure"), std::string::npos) << msg;
  EXPECT_NE(msg.find("0.1 s"), std::string::npos) << msg;  // what is allowed: 1 / frame rate
}

TEST(BrownianKeys, NeighbourPredictionWithoutARadiusIsNamed) {
  const Case c = blankCase("brownian-neighbours", "[link]\npredict = \"neighbours\"\n");
  const std::string msg = inputErrorOf([&] { trackerConfig(c); });
  EXPECT_NE(msg.find("link.predict"), std::string::npos) << msg;
  EXPECT_NE(msg.find("link.neighbour_radius"), std::string::npos) << msg;
}

TEST(BrownianPipeline, AutoPicksFlowForAFlowVideoAndKeepsItsOutputs) {
  SynthOptions o;
  o.width = 200;
  o.height = 150;
  o.frames = 20;
  o.particles = 20;
  o.seed = 4;
  const fs::path dir = render("brownian-auto-flow", o);
  TrackConfig c;  // analysis.motion auto
  FrameSource src((dir / "frames").string());
  const TrackRun run = runTracker(src, c, true);
  EXPECT_EQ(run.motion.model, MotionModel::flow) << run.motion.reason;
  const auto files = writeTrackOutputs(run, c, dir / "out", nlohmann::json::object());
  for (const char* f : {"tracks.csv", "velocities.csv", "retention.csv", "speed_map.png", "velocity_overlay.png", "summary.json"})
    EXPECT_NE(std::find(files.begin(), files.end(), f), files.end()) << f;
  const auto j = summaryOf(dir / "out");
  EXPECT_EQ(j["motion"]["model"], "flow");
  // The persistence counts are numbers in summary.json, the decision's own.
  const auto& n = j["motion"]["numbers"];
  ASSERT_TRUE(n.contains("persistence_tracks")) << n.dump();
  EXPECT_EQ(n["persistence_tracks"].get<int>(), run.motion.persistence_tracks);
  EXPECT_EQ(n["persistent_tracks"].get<int>(), run.motion.persistent_tracks);
  EXPECT_NEAR(n["persistent_expected"].get<double>(), 0.01 * run.motion.persistence_tracks, 1e-12);
  EXPECT_GT(run.motion.persistence_tracks, 0);
}

namespace {
/// Free diffusion only (no flow, grains, stuck or deposited particles): D 0.8 px^2 per frame at
/// 10 fps and 0.5 um/px.
SynthOptions diffusionVideo(int width, int height, int frames, int particles, std::uint64_t seed) {
  SynthOptions o;
  o.width = width;
  o.height = height;
  o.frames = frames;
  o.particles = particles;
  o.immobile = 0;
  o.grains = 0;
  o.speed = 0;
  o.deposit_fraction = 0;
  o.brownian_d = 0.8;  // px^2 per frame
  o.fps = 10;
  o.pixel_size = 0.5e-6;
  o.seed = seed;
  return o;
}
}  // namespace

TEST(BrownianPipeline, AutoPicksBrownianForADiffusionVideo) {
  const SynthOptions o = diffusionVideo(240, 180, 40, 60, 21);
  const fs::path dir = render("brownian-auto-diffusion", o);
  TrackConfig c;
  c.fps = o.fps;
  c.pixel_size = o.pixel_size;
  FrameSource src((dir / "frames").string());
  const TrackRun run = runTracker(src, c, true);
  EXPECT_EQ(run.motion.model, MotionModel::brownian) << run.motion.reason;
  EXPECT_TRUE(run.motion.relinked);
  const auto files = writeTrackOutputs(run, c, dir / "out", nlohmann::json::object());
  for (const char* f : {"tracks.csv", "track_diffusion.csv", "msd.csv", "van_hove.csv", "diffusion_histogram.csv", "diffusion_histogram.png", "dispersion.csv"})
    EXPECT_NE(std::find(files.begin(), files.end(), f), files.end()) << f;
  for (const char* f : {"retention.csv", "speed_map.png", "velocities.csv"}) EXPECT_EQ(std::find(files.begin(), files.end(), f), files.end()) << f;
  const auto j = summaryOf(dir / "out");
  const double d_true = o.brownian_d * o.pixel_size * o.pixel_size * o.fps / kUm2;  // um^2/s
  const double d = j["brownian"]["D_um2_per_s"].get<double>(), se = j["brownian"]["D_se_um2_per_s"].get<double>();
  std::printf("video: D %.4f +- %.4f um^2/s (true %.4f), alpha %.3f +- %.3f, sigma %.4f um; %s\n", d, se, d_true, j["brownian"]["alpha"].get<double>(),
              j["brownian"]["alpha_se"].get<double>(), j["brownian"]["sigma_loc_um"].get<double>(), j["motion"]["reason"].get<std::string>().c_str());
  // 4 standard errors, plus 3 % for what the video adds (particles overlapping, leaving the view).
  EXPECT_NEAR(d, d_true, 4 * se + 0.03 * d_true);
  EXPECT_FALSE(j.contains("retained_fraction"));
  std::ifstream disp(dir / "out" / "dispersion.csv");
  std::string header;
  std::getline(disp, header);
  EXPECT_NE(header.find("drift_x_um,drift_y_um"), std::string::npos);
}

TEST(BrownianPipeline, AutoLinksAsBrownianDoesAndWritesTheSameFilesOnOneOrTwoThreads) {
  // analysis.motion "auto" links the detections a second time, without prediction, while
  // the frames are detected; once the tracks are judged Brownian those are the tracks: the
  // same, point for point, as a run told "brownian" from the start (which links without
  // prediction only). And the output files written by two threads (writeTrackOutputs) are
  // those one thread writes, byte for byte, in the same order (summary.json aside: it
  // holds the run's seconds).
  const SynthOptions o = diffusionVideo(200, 150, 30, 40, 22);
  const fs::path dir = render("brownian-auto-relink", o);
  TrackConfig c;
  c.fps = o.fps;
  c.pixel_size = o.pixel_size;
  c.threads = 2;
  TrackConfig told = c;
  told.analysis.motion = MotionModel::brownian;
  FrameSource a((dir / "frames").string()), b((dir / "frames").string());
  const TrackRun automatic = runTracker(a, c, true), brownian = runTracker(b, told, true);
  ASSERT_EQ(automatic.motion.model, MotionModel::brownian) << automatic.motion.reason;
  EXPECT_TRUE(automatic.motion.relinked);
  EXPECT_GT(automatic.tracks.points.size(), 500u);
  ASSERT_EQ(automatic.tracks.points.size(), brownian.tracks.points.size());
  for (std::size_t i = 0; i < automatic.tracks.points.size(); ++i) {
    EXPECT_EQ(automatic.tracks.points[i].particle, brownian.tracks.points[i].particle) << i;
    EXPECT_EQ(automatic.tracks.points[i].frame, brownian.tracks.points[i].frame) << i;
    EXPECT_EQ(automatic.tracks.points[i].x_px, brownian.tracks.points[i].x_px) << i;
  }
  EXPECT_EQ(automatic.link.links, brownian.link.links);
  EXPECT_EQ(automatic.link.gap_closures, brownian.link.gap_closures);
  TrackConfig one = c;
  one.threads = 1;
  const auto files2 = writeTrackOutputs(automatic, c, dir / "out2", nlohmann::json::object());
  const auto files1 = writeTrackOutputs(automatic, one, dir / "out1", nlohmann::json::object());
  EXPECT_EQ(files2, files1);
  EXPECT_NE(std::find(files2.begin(), files2.end(), "tracks.vtp"), files2.end());
  EXPECT_NE(std::find(files2.begin(), files2.end(), "streamlines.png"), files2.end());
  auto bytes = [](const fs::path& f) {
    std::ifstream in(f, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  for (const auto& f : files1) {
    ASSERT_TRUE(fs::exists(dir / "out2" / f)) << f;
    if (f != "summary.json") {
      EXPECT_TRUE(bytes(dir / "out1" / f) == bytes(dir / "out2" / f)) << f << " differs between one and two threads";
    }
  }
}

}  // namespace
}  // namespace mmval::tracking
