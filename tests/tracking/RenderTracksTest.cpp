// A simulation's trajectories drawn as a microscope video (RenderTracks.hpp) keep the
// simulation's clock: the tracker's frame k, at t = k / fps, is the simulation's output step k.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>
#include <filesystem>

#include <opencv2/core.hpp>

#include "mmval/tracking/Frames.hpp"
#include "mmval/tracking/Pipeline.hpp"
#include "mmval/tracking/RenderTracks.hpp"

namespace mmval::tracking {
namespace {

namespace fs = std::filesystem;

constexpr double kDt = 0.025;     // s between output steps (40 frames/s)
constexpr double kPixel = 10e-6;  // m per geometry pixel
constexpr double kSpeedPx = 3.0;  // px per step along x

/// Five particles crossing a 140 x 90 px glass window along x, written from step `first` to 30
/// with t = t_of(step): the first steps have no particle, as when a run's first fines enter late.
template <class TimeOf>
Tracks crossing(int first, TimeOf t_of) {
  Tracks t;
  for (int p = 0; p < 5; ++p)
    for (int f = first; f <= 30; ++f) {
      TrackPoint q;
      q.frame = f;
      q.particle = p;
      q.t = t_of(f);
      q.x_px = 20 + kSpeedPx * f;
      q.y_px = 10 + 16 * p;
      q.x = q.x_px * kPixel;
      q.y = q.y_px * kPixel;
      q.state = "mobile";
      t.points.push_back(q);
    }
  t.source = "crossing";
  return t;
}

fs::path scratch(const char* name) {
  const fs::path dir = fs::temp_directory_path() / name;
  fs::remove_all(dir);
  return dir;
}

TEST(RenderTracks, VideoStartsAtTheSimulationsStepZeroAndTracksKeepItsClock) {
  const Tracks sim = crossing(3, [](int f) { return f * kDt; });
  const cv::Mat glass = cv::Mat::zeros(90, 140, CV_8U);
  const fs::path dir = scratch("mmval-render-clock");
  const RenderedVideo video = renderTracksVideo(sim, glass, kPixel, RenderOptions{}, dir);
  // Steps 0-2 are empty frames of the video: 31 frames, frame k = step k.
  EXPECT_EQ(video.frames, 31);
  EXPECT_NEAR(video.fps, 1.0 / kDt, 1e-9);
  EXPECT_TRUE(fs::exists(dir / "frames" / "frame_00000.png"));
  EXPECT_TRUE(fs::exists(dir / "frames" / "frame_00030.png"));
  EXPECT_FALSE(fs::exists(dir / "frames" / "frame_00031.png"));
  ASSERT_FALSE(video.truth.points.empty());
  for (const auto& p : video.truth.points) EXPECT_NEAR(p.frame * kDt, p.t, 1e-12);

  // The tracker's times are frame / fps from its first frame: with the video on the
  // simulation's clock, each tracked position is where the trajectory was at that time
  // (a 3-step offset would put it 9 px behind).
  TrackConfig c;
  c.fps = video.fps;
  c.pixel_size = kPixel;
  FrameSource src((dir / "frames").string());
  const TrackRun run = runTracker(src, c, true);
  ASSERT_GT(run.tracks.points.size(), 100u);
  // Signed x error of every tracked point against the trajectory at the point's time: its median
  // is sub-pixel (a one-step offset of the clock would make it 3 px); the odd split spot at SNR 8
  // lands ~1 px off, so the bulk is checked by quantiles, not by the worst point.
  std::vector<double> dx;
  for (const auto& p : run.tracks.points) dx.push_back(p.x_px - (20 + kSpeedPx * p.t / kDt));
  std::sort(dx.begin(), dx.end());
  const auto quantile = [&](double q) { return dx[static_cast<std::size_t>(q * (dx.size() - 1))]; };
  EXPECT_LT(std::abs(quantile(0.5)), 0.1) << "median px between a tracked position and the trajectory at the same time";
  EXPECT_LT(quantile(0.95) - quantile(0.05), 0.5) << "px";
  std::printf("tracked - trajectory at the same time: median %.3f px, 5-95 %% %.3f .. %.3f px\n", quantile(0.5), quantile(0.05), quantile(0.95));
  fs::remove_all(dir);
}

TEST(RenderTracks, StepsOffTheClockStartTheVideoAtTheFirstStepWritten) {
  // t is not step * dt (e.g. a window cut from a longer run, its steps renumbered): the video
  // cannot place the missing steps on a clock and starts at the first step written.
  const Tracks sim = crossing(3, [](int f) { return 1.0 + (f - 3) * kDt; });
  const cv::Mat glass = cv::Mat::zeros(90, 140, CV_8U);
  const fs::path dir = scratch("mmval-render-offclock");
  const RenderedVideo video = renderTracksVideo(sim, glass, kPixel, RenderOptions{}, dir);
  EXPECT_EQ(video.frames, 28);
  for (const auto& p : video.truth.points) EXPECT_NEAR(1.0 + p.frame * kDt, p.t, 1e-12);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mmval::tracking
