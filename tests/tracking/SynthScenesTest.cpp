// The scenes of `mmval synth` called as library functions (SynthScenes.hpp), no process:
// the written truth against what the settings say, and the flag -> case-key mapping of
// `mmval track` (TrackpyFlags.hpp) against docs/trackpy-mapping.md.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <variant>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "../TestScratch.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Tracks.hpp"
#include "mmval/tracking/SynthScenes.hpp"
#include "mmval/tracking/TrackpyFlags.hpp"

namespace mmval::tracking {
namespace {

namespace fs = std::filesystem;

/// truth.csv holds positions to 6 significant digits: below 1000 px, within 5e-4 px each.
constexpr double kCsvPositionTolPx = 1e-3;

std::map<std::int64_t, std::vector<TrackPoint>> byParticle(const Tracks& t) {
  std::map<std::int64_t, std::vector<TrackPoint>> out;
  for (const TrackPoint& p : t.points) out[p.particle].push_back(p);
  return out;
}

// The flow scene with a pore image and an injected uniform flow (no fluid solve): the
// solver receives the thresholded grains and the speed; every particle steps exactly the
// flow's displacement per frame or stands still (deposited, immobile, or held off a grain).
TEST(SynthScenes, FlowSceneTakesInjectedFlowAndGeometry) {
  const fs::path dir = test::scratch("synth-flow-scene");
  fs::remove_all(dir);
  fs::create_directories(dir);
  // 96 x 64 px of bright pore with one dark disc grain of radius 8 px at (48, 32).
  cv::Mat image(64, 96, CV_8U, cv::Scalar(255));
  cv::circle(image, {48, 32}, 8, cv::Scalar(0), -1);
  const fs::path geometry = dir / "pores.png";
  ASSERT_TRUE(cv::imwrite(geometry.string(), image));

  SynthSharedSettings shared;
  shared.frames = 6;
  shared.particles = 5;
  shared.pixel_size_um = 2.0;
  shared.fps_hz = 4.0;
  shared.seed = 11;
  FlowSceneSettings s;
  s.video.immobile = 2;
  s.video.speed = 1.5;
  applySharedSettings(shared, s.video);
  s.geometry = geometry;
  s.dark_grains = true;
  const cv::Point2d step_px{1.5, 0.0};
  int grain_pixels = -1;
  double speed_given = -1;
  auto uniform = [&](const cv::Mat& grains, double speed) -> SynthFlowField {
    grain_pixels = cv::countNonZero(grains);
    speed_given = speed;
    return [step_px](double, double) { return step_px; };
  };
  const fs::path out = dir / "video";
  const SynthResult r = writeFlowScene(s, out, uniform);

  EXPECT_EQ(speed_given, 1.5);
  // The disc's pixel count, pi 8^2 = 201, within the rasterised edge (+-2 pi r ~ 50).
  EXPECT_NEAR(grain_pixels, M_PI * 64, 50);
  ASSERT_EQ(r.frames.size(), 6u);
  EXPECT_EQ(fs::path(r.frames.front()).parent_path().parent_path(), fs::absolute(out));  // in the committed folder
  const cv::Mat frame0 = cv::imread(r.frames.front(), cv::IMREAD_GRAYSCALE);
  EXPECT_EQ(frame0.cols, 96);  // the geometry's size, not the default 320 x 240
  EXPECT_EQ(frame0.rows, 64);
  EXPECT_EQ(r.immobile, 2);

  const Tracks truth = readTracksCsv(out / "truth.csv");
  std::map<std::int64_t, int> per_frame;
  for (const TrackPoint& p : truth.points) ++per_frame[p.frame];
  ASSERT_EQ(per_frame.size(), 6u);
  for (const auto& fc : per_frame) EXPECT_EQ(fc.second, 5 + 2) << "frame " << fc.first;  // moving ones are replaced as they leave
  int moving_steps = 0;
  for (const auto& track : byParticle(truth)) {
    const auto& pts = track.second;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      EXPECT_NEAR(pts[i].t, pts[i].frame / 4.0, 1e-9);
      EXPECT_NEAR(pts[i].x, pts[i].x_px * 2e-6, 2e-6 * kCsvPositionTolPx);
      if (i == 0) continue;
      ASSERT_EQ(pts[i].frame, pts[i - 1].frame + 1);
      const double dx = pts[i].x_px - pts[i - 1].x_px, dy = pts[i].y_px - pts[i - 1].y_px;
      EXPECT_NEAR(dy, 0.0, kCsvPositionTolPx) << "particle " << track.first;
      const bool moved = std::abs(dx - step_px.x) <= kCsvPositionTolPx, still = std::abs(dx) <= kCsvPositionTolPx;
      EXPECT_TRUE(moved || still) << "particle " << track.first << " frame " << pts[i].frame << " dx " << dx;
      moving_steps += moved;
    }
  }
  EXPECT_GT(moving_steps, 10);
}

TEST(SynthScenes, FlowSolverFailureNamesGeometry) {
  const fs::path dir = test::scratch("synth-flow-fail");
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path geometry = dir / "pores.png";
  ASSERT_TRUE(cv::imwrite(geometry.string(), cv::Mat(40, 60, CV_8U, cv::Scalar(255))));
  FlowSceneSettings s;
  s.geometry = geometry;
  auto failing = [](const cv::Mat&, double) -> SynthFlowField { throw std::runtime_error("no pore path"); };
  try {
    writeFlowScene(s, dir / "video", failing);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().key, "--geometry");
    EXPECT_EQ(e.where().file, geometry.string());
    EXPECT_EQ(e.problem(), "no pore path");
  }
  EXPECT_FALSE(fs::exists(dir / "video"));
  EXPECT_THROW(writeFlowScene(s, dir / "video", nullptr), std::invalid_argument);
}

// The ring scene: every colloid in every frame, at the shared settings given, kept 1.5 ring
// radii from the edges (SynthRings.hpp), truth.json echoing the settings.
TEST(SynthScenes, RingSceneWritesTheGivenSettings) {
  const fs::path out = test::scratch("synth-ring-scene");
  fs::remove_all(out);
  RingSceneOptions rings;
  rings.ring_radius_px = 5;
  SynthSharedSettings shared;
  shared.width = 128;
  shared.height = 96;
  shared.frames = 4;
  shared.particles = 3;
  shared.pixel_size_um = 0.3;
  shared.seed = 4;
  applySharedSettings(shared, rings);
  EXPECT_EQ(rings.fps_hz, RingSceneOptions{}.fps_hz);  // not given: the scene's default
  writeRingSceneFolder(rings, out);

  const Tracks truth = readTracksCsv(out / "truth.csv");
  ASSERT_EQ(truth.points.size(), 3u * 4u);
  for (const TrackPoint& p : truth.points) {
    EXPECT_GE(p.x_px, 1.5 * 5 - kCsvPositionTolPx);
    EXPECT_LE(p.x_px, 128 - 1.5 * 5 + kCsvPositionTolPx);
    EXPECT_GE(p.y_px, 1.5 * 5 - kCsvPositionTolPx);
    EXPECT_LE(p.y_px, 96 - 1.5 * 5 + kCsvPositionTolPx);
    EXPECT_NEAR(p.x, p.x_px * 0.3e-6, 0.3e-6 * kCsvPositionTolPx);
  }
  std::ifstream json_file(out / "truth.json");
  const nlohmann::json j = nlohmann::json::parse(json_file);
  EXPECT_EQ(j.at("width_px").get<int>(), 128);
  EXPECT_EQ(j.at("height_px").get<int>(), 96);
  EXPECT_EQ(j.at("particles").get<int>(), 3);
  EXPECT_EQ(j.at("seed").get<int>(), 4);
  EXPECT_NEAR(j.at("pixel_size_um").get<double>(), 0.3, 1e-12);
}

TEST(SynthScenes, RingsThatDoNotFitNameTheFlags) {
  const fs::path out = test::scratch("synth-ring-crowded");
  fs::remove_all(out);
  RingSceneOptions rings;
  rings.particles = 500;
  try {
    writeRingSceneFolder(rings, out);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(e.expected().find("--particles"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(out));
}

TEST(SynthScenes, SlabRefusesBothWaysOfSettingD) {
  const fs::path out = test::scratch("synth-slab-d");
  fs::remove_all(out);
  SlabSceneSettings s;
  s.slab.diffusion_um2_s = 1;
  s.diffusion_given = true;
  s.stokes_einstein_given = true;
  try {
    writeSlabScene(s, out);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.got(), "--diffusion-um2s 1");
  }
  EXPECT_FALSE(fs::exists(out));
}

TEST(SynthScenes, SharedSettingsCheckNamesTheFlag) {
  SynthSharedSettings shared;
  shared.fps_hz = std::nan("");
  try {
    checkSynthSharedSettings(shared, 3);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.got(), "--fps nan");
  }
  EXPECT_THROW(checkSynthSharedSettings({}, -1), InputError);  // --speed
  EXPECT_NO_THROW(checkSynthSharedSettings({}, 0));
}

// docs/trackpy-mapping.md, the --diameter and --minmass rows.
TEST(TrackpyFlags, KeysFollowTheDocumentedMapping) {
  TrackpyFlags f;
  f.diameter = "9";
  f.minmass = "140";
  f.invert = true;
  std::map<std::string, Value> keys;
  for (const TrackpyKey& k : trackpyKeys(f)) keys[k.key] = k.value;
  EXPECT_EQ(std::get<std::string>(keys.at("detect.method")), "peaks");
  EXPECT_EQ(std::get<std::int64_t>(keys.at("detect.refine_radius")), 4);     // D // 2
  EXPECT_EQ(std::get<std::int64_t>(keys.at("detect.local_background")), 4);  // D // 2
  EXPECT_EQ(std::get<std::int64_t>(keys.at("detect.separation")), 10);       // D + 1
  EXPECT_NEAR(std::get<double>(keys.at("detect.min_mass_relative")), 140.0 / 255.0, 1e-15);
  EXPECT_EQ(std::get<std::string>(keys.at("detect.polarity")), "dark");
  EXPECT_FALSE(std::get<bool>(keys.at("detect.subtract_background")));

  f.separation = "6.6";  // replaces D + 1, rounded
  for (const TrackpyKey& k : trackpyKeys(f))
    if (k.key == "detect.separation") {
      EXPECT_EQ(std::get<std::int64_t>(k.value), 7);
    }
}

TEST(TrackpyFlags, BadValuesNameTheFlag) {
  const std::pair<const char*, std::string TrackpyFlags::*> flags[] = {
      {"--diameter", &TrackpyFlags::diameter}, {"--minmass", &TrackpyFlags::minmass}, {"--memory", &TrackpyFlags::memory}};
  for (const auto& flag : flags) {
    TrackpyFlags f;
    f.*flag.second = "4.5";
    if (std::string(flag.first) == "--minmass") f.*flag.second = "-1";
    try {
      trackpyKeys(f);
      ADD_FAILURE() << flag.first << ": expected InputError";
    } catch (const InputError& e) {
      EXPECT_EQ(e.got().rfind(flag.first, 0), 0u) << e.what();
    }
  }
  TrackpyFlags even;
  even.diameter = "4";
  EXPECT_THROW(trackpyKeys(even), InputError);  // trackpy requires an odd diameter
}

}  // namespace
}  // namespace mmval::tracking
