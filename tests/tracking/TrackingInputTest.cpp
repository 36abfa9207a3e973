// Bad and unusual input: each case ends in a clear message naming the
// file and what is wrong, or is handled correctly. Unit tier: well under a second
// each. Complements Frames.BadInputsAreNamed in FramesTest.cpp (empty folder,
// images of different sizes, a file that is not a video, a glob that matches nothing).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <filesystem>
#include <fstream>
#include <string>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "mmval/core/Case.hpp"
#include "mmval/core/CaseKind.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/tracking/Detect.hpp"
#include "mmval/tracking/Frames.hpp"
#include "mmval/tracking/Kinds.hpp"
#include "mmval/tracking/Pipeline.hpp"
#include "mmval/tracking/TrackMetrics.hpp"
#include "../InputErrorMessage.hpp"

namespace mmval::tracking {
namespace {

namespace fs = std::filesystem;

fs::path scratch(const std::string& name) {
  const fs::path d = fs::path(MMVAL_BINARY_DIR) / "test-output" / "tracking-input" / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

/// Dark Gaussian spots (sigma 1.5 px, depth `depth`) on a flat `level`, as 16-bit.
cv::Mat spots16(const std::vector<cv::Point2d>& at, double level, double depth) {
  cv::Mat img(80, 100, CV_64F, cv::Scalar(level));
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x)
      for (const auto& p : at) img.at<double>(y, x) -= depth * std::exp(-((x - p.x) * (x - p.x) + (y - p.y) * (y - p.y)) / (2 * 1.5 * 1.5));
  cv::Mat out;
  img.convertTo(out, CV_16U);
  return out;
}

std::string messageOf(const std::function<void()>& f) { return mmval::test::inputErrorMessage(f); }

TEST(TrackingInput, TruncatedVideoSaysWhereItEnds) {
  const fs::path d = scratch("truncated");
  const fs::path avi = d / "cut.avi";
  {
    cv::VideoWriter w(avi.string(), cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 10, cv::Size(64, 48), false);
    ASSERT_TRUE(w.isOpened());
    cv::Mat f(48, 64, CV_8U);
    for (int k = 0; k < 20; ++k) {
      cv::randu(f, 0, 255);  // noise: every frame a large JPEG, so the cut falls mid-video
      w.write(f);
    }
  }
  // Keep the first 60 % of the bytes: the header (and its frame count) survives, the
  // tail of the frames does not.
  const auto size = fs::file_size(avi);
  fs::resize_file(avi, size * 6 / 10);
  const std::string msg = messageOf([&] {
    FrameSource src(avi.string());
    cv::Mat f;
    int i = 0;
    while (src.next(f, i)) {
    }
  });
  std::printf("truncated video: %s\n", msg.c_str());
  // Either it cannot be opened at all, or it says it ends early; both name the file.
  EXPECT_NE(msg.find("cut.avi"), std::string::npos) << msg;
  EXPECT_TRUE(msg.find("ends early") != std::string::npos || msg.find("cannot open") != std::string::npos) << msg;
}

TEST(TrackingInput, UnreadableImageInAFolderIsNamed) {
  const fs::path d = scratch("unreadable");
  cv::imwrite((d / "a.png").string(), cv::Mat(20, 30, CV_8U, cv::Scalar(100)));
  std::ofstream(d / "b.png") << "\x89PNG but not really";
  FrameSource src(d.string());
  cv::Mat f;
  int i = 0;
  EXPECT_TRUE(src.next(f, i));
  const std::string msg = messageOf([&] { src.next(f, i); });
  EXPECT_NE(msg.find("b.png"), std::string::npos) << msg;
  EXPECT_NE(msg.find("cannot read"), std::string::npos) << msg;
}

TEST(TrackingInput, SixteenBitTiffSpotsAreLocated) {
  // 12-bit data in 16-bit containers (a scientific camera): background 3000 counts,
  // spots 1200 counts deep. Reference: the rendered positions; tolerance 0.05 px
  // (noise-free spots; the Gaussian-masked centroid recovers them to ~1e-3 px).
  const std::vector<cv::Point2d> truth = {{30.3, 40.6}, {70.8, 20.2}};
  const fs::path d = scratch("tiff16");
  for (int k = 0; k < 2; ++k) ASSERT_TRUE(cv::imwrite((d / ("f" + std::to_string(k) + ".tif")).string(), spots16(truth, 3000, 1200)));
  // ... and the same frames as one multi-page TIFF.
  const fs::path stack = d / "stack.tiff";
  ASSERT_TRUE(cv::imwritemulti(stack.string(), std::vector<cv::Mat>{spots16(truth, 3000, 1200), spots16(truth, 3000, 1200)}));
  for (const std::string& input : {(d / "*.tif").string(), stack.string()}) {
    FrameSource src(input);
    EXPECT_EQ(src.count(), 2) << input;
    cv::Mat f;
    int i = 0;
    ASSERT_TRUE(src.next(f, i));
    EXPECT_EQ(f.type(), CV_32F);
    DetectOptions o;
    o.subtract_background = false;
    const auto found = detect(f, {}, Polarity::automatic, o);
    ASSERT_EQ(found.size(), truth.size()) << input;
    for (const auto& t : truth) {
      double best = 1e9;
      for (const auto& p : found) best = std::min(best, std::hypot(p.x - t.x, p.y - t.y));
      EXPECT_LT(best, 0.05) << input << ": spot at " << t.x << ", " << t.y;
    }
  }
}

CaseKindRegistry& registry() {
  static CaseKindRegistry r = [] {
    CaseKindRegistry reg;
    registerTrackingKinds(reg);
    return reg;
  }();
  return r;
}

/// Three blank 40 x 40 frames: nothing to find.
fs::path blankFrames(const std::string& name) {
  const fs::path d = scratch(name);
  for (int k = 0; k < 3; ++k) cv::imwrite((d / ("f" + std::to_string(k) + ".png")).string(), cv::Mat(40, 40, CV_8U, cv::Scalar(128)));
  return d;
}

TEST(TrackingInput, MissingPixelSizeIsNamed) {
  const fs::path d = blankFrames("no-pixel-size");
  const Case c = Case::parse("[case]\nname = \"t\"\nkind = \"tracking-video\"\n[inputs]\nvideo = \"" + d.string() + "\"\nframe_rate = \"10 Hz\"\n",
                             d / "case.toml", registry());
  const std::string msg = messageOf([&] { runTrackingVideo(c, {d / "out", true}); });
  EXPECT_NE(msg.find("inputs.pixel_size"), std::string::npos) << msg;
  EXPECT_NE(msg.find("--pixel-size-um"), std::string::npos) << msg;
}

TEST(TrackingInput, NoParticlesGivesZerosNotNan) {
  // Blank frames through the whole tracking-video run: no detections, no tracks, and
  // every metric a finite number (the command then warns: see apps/TrackCommands.cpp).
  const fs::path d = blankFrames("no-particles");
  const Case c = Case::parse("[case]\nname = \"t\"\nkind = \"tracking-video\"\n[inputs]\nvideo = \"" + d.string() +
                                 "\"\nframe_rate = \"10 Hz\"\npixel_size = \"1 um\"\n",
                             d / "case.toml", registry());
  const RunOutput out = runTrackingVideo(c, {d / "out", true});
  EXPECT_EQ(out.details.value("detections", -1), 0);
  for (const char* m : {"sigma_x", "sigma_y", "tracks", "immobile", "retention_fraction"}) {
    ASSERT_TRUE(out.metrics.count(m)) << m;
    EXPECT_TRUE(std::isfinite(out.metrics.at(m))) << m << " = " << out.metrics.at(m);
  }
}

TEST(TrackingInput, DispersionOfParticlesThatNeverMoveIsZero) {
  // Three particles sitting still for ten frames: all immobile, no mobile positions, so
  // no spread: sigma_x = sigma_y = 0 exactly (it was NaN, the mean of nothing).
  Tracks t;
  for (int id = 0; id < 3; ++id)
    for (int f = 0; f < 10; ++f) {
      TrackPoint p;
      p.frame = f;
      p.particle = id;
      p.t = 0.1 * f;
      p.x = (10.0 + 20 * id) * 1e-6;
      p.y = 15e-6;
      t.points.push_back(p);
    }
  const TrackStats s = analyseTracks(t, TrackOptions{});
  EXPECT_EQ(s.immobile, 3);
  EXPECT_EQ(s.mobile, 0);
  EXPECT_TRUE(std::isfinite(s.sigma_x) && std::isfinite(s.sigma_y));
  EXPECT_NEAR(s.sigma_x, 0.0, 1e-15);
  EXPECT_NEAR(s.sigma_y, 0.0, 1e-15);
}

}  // namespace
}  // namespace mmval::tracking

namespace mmval::tracking {
namespace {

TEST(TrackingInput, ThreadedReadingGivesTheSameTracksAndTheSameErrors) {
  // Image folders are read and detected by several workers out of order and linked in
  // order: the result must be the single-threaded one, point for point (round-off class:
  // the same arithmetic per frame), and a bad frame must still stop the run by name.
  const fs::path d = scratch("threads");
  for (int k = 0; k < 6; ++k) {
    const double shift = 1.7 * k;
    cv::Mat f16 = spots16({{20 + shift, 30.2}, {60.4, 25 + shift}, {45.5 + shift, 60.1}}, 3000, 1200);
    cv::Mat f8;
    f16.convertTo(f8, CV_8U, 255.0 / 3000.0);
    cv::imwrite((d / ("f" + std::to_string(k) + ".png")).string(), f8);
  }
  TrackConfig one;
  one.detect.subtract_background = false;
  TrackConfig two = one;
  two.threads = 2;
  FrameSource a(d.string()), b(d.string());
  const TrackRun r1 = runTracker(a, one, true), r2 = runTracker(b, two, true);
  ASSERT_EQ(r1.tracks.points.size(), r2.tracks.points.size());
  EXPECT_EQ(r1.tracks.points.size(), 18u);
  for (std::size_t i = 0; i < r1.tracks.points.size(); ++i) {
    EXPECT_EQ(r1.tracks.points[i].frame, r2.tracks.points[i].frame);
    EXPECT_EQ(r1.tracks.points[i].particle, r2.tracks.points[i].particle);
    EXPECT_NEAR(r1.tracks.points[i].x_px, r2.tracks.points[i].x_px, 1e-12);
    EXPECT_NEAR(r1.tracks.points[i].y_px, r2.tracks.points[i].y_px, 1e-12);
  }
  cv::imwrite((d / "f9.png").string(), cv::Mat(10, 10, CV_8U, cv::Scalar(200)));
  FrameSource bad(d.string());
  const std::string msg = messageOf([&] { runTracker(bad, two, true); });
  EXPECT_NE(msg.find("f9.png"), std::string::npos) << msg;
  EXPECT_NE(msg.find("frame size differs"), std::string::npos) << msg;
}

}  // namespace
}  // namespace mmval::tracking
