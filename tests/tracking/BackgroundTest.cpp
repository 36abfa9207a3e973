// The static background: per-pixel quantiles against hand-built frames, and a
// rolling background that follows an illumination drift the single median of a
// long video cannot.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mmval/tracking/Background.hpp"
#include "mmval/tracking/Pipeline.hpp"

namespace mmval::tracking {
namespace {

namespace fs = std::filesystem;

TEST(Background, QuantileOfFramesPicksTheRank) {
  std::vector<cv::Mat> frames;
  for (double v : {0.3, 0.1, 0.5, 0.2, 0.4}) frames.emplace_back(3, 4, CV_32F, cv::Scalar(v));
  const auto at = [&](double q) { return quantileOfFrames(frames, q).at<float>(1, 2); };
  EXPECT_FLOAT_EQ(at(0.0), 0.1f);
  EXPECT_FLOAT_EQ(at(0.5), 0.3f);  // rank floor(2.5) = 2: the median of five
  EXPECT_FLOAT_EQ(at(0.8), 0.5f);  // rank 4
  EXPECT_FLOAT_EQ(at(1.0), 0.5f);
  EXPECT_THROW(quantileOfFrames(frames, 1.5), std::invalid_argument);
  EXPECT_TRUE(quantileOfFrames({}, 0.5).empty());
}

/// 120 frames whose background brightens from 0.35 to 0.85, with dark spots drifting
/// across; returns the folder. `level(f)` is the true background of frame f.
fs::path driftingVideo(const std::string& name) {
  const fs::path dir = fs::path(MMVAL_BINARY_DIR) / "test-output" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  for (int f = 0; f < 120; ++f) {
    const double level = 0.35 + 0.5 * f / 119.0;
    cv::Mat img(80, 120, CV_32F, cv::Scalar(level));
    for (int k = 0; k < 6; ++k) cv::circle(img, cv::Point((10 + 3 * f + 20 * k) % 120, 10 + 12 * k), 3, cv::Scalar(level - 0.25), -1);
    cv::Mat out;
    img.convertTo(out, CV_8U, 255.0);
    cv::imwrite((dir / fmt::format("frame_{:04d}.png", f)).string(), out);
  }
  return dir;
}

TEST(Background, RollingFollowsAnIlluminationDriftTheMedianCannot) {
  const fs::path dir = driftingVideo("background-drift");
  FrameSource src(dir.string());
  const RollingBackground rb = rollingBackground(src, 20, 10, 0.5);
  ASSERT_EQ(rb.backgrounds.size(), 6u);
  EXPECT_EQ(rb.centres.front(), 9);
  std::vector<cv::Mat> all;
  cv::Mat f;
  int index = 0;
  src.rewind();
  while (src.next(f, index)) all.push_back(f.clone());
  const cv::Mat global = quantileOfFrames(all, 0.5);
  // Background error at a pixel no spot crosses (row 75), first, middle and last frames:
  // the rolling background is within the drift over half a block (~0.05 / 2) plus
  // 8-bit rounding; the single median misses the ends by ~0.25.
  for (int fr : {0, 60, 119}) {
    const double truth = std::round(255 * (0.35 + 0.5 * fr / 119.0)) / 255;
    const double rolling = rb.at(fr).at<float>(75, 60), single = global.at<float>(75, 60);
    EXPECT_NEAR(rolling, truth, 0.05) << "frame " << fr;
    if (fr != 60) {
      EXPECT_GT(std::abs(single - truth), 0.2) << "frame " << fr;
    }
  }
  // Between block centres the blend is linear: exact halfway between two blocks.
  const int a = rb.centres[2], b = rb.centres[3];
  const cv::Mat mid = rb.at((a + b) / 2);
  EXPECT_NEAR(mid.at<float>(75, 60), 0.5 * (rb.backgrounds[2].at<float>(75, 60) + rb.backgrounds[3].at<float>(75, 60)), 0.03);
}

// Through the tracker: the six spots per frame of the drifting video, found with the
// rolling background in every frame; printed against the single median.
TEST(Background, TrackerWithRollingBackgroundFindsEverySpotOfADriftingVideo) {
  const fs::path dir = driftingVideo("background-drift-tracker");
  for (int window : {0, 20}) {
    TrackConfig c;
    c.detect.polarity = Polarity::dark;
    c.background_window = window;
    FrameSource src(dir.string());
    const TrackRun run = runTracker(src, c, true);
    int exact = 0;
    std::size_t total = 0;
    for (const auto& d : run.detections) {
      exact += d.size() == 6 ? 1 : 0;
      total += d.size();
    }
    std::printf("background window %d: %d of %zu frames with exactly the 6 spots, %zu detections\n", window, exact, run.detections.size(), total);
    if (window > 0) {
      EXPECT_EQ(exact, static_cast<int>(run.detections.size()));
    }
  }
}

}  // namespace
}  // namespace mmval::tracking
