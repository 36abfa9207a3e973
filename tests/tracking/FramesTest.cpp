// Frame sources (Frames.hpp): a video file, frame ranges and a region of
// interest, and the errors for unusable inputs.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include "mmval/core/Error.hpp"
#include "mmval/tracking/Frames.hpp"
#include "mmval/tracking/Pipeline.hpp"
#include "SyntheticVideo.hpp"

namespace mmval::tracking {
namespace {

namespace fs = std::filesystem;

TEST(Frames, VideoFileAndRangeAndRoi) {
  SynthOptions o;
  o.frames = 12;
  SynthResult truth;
  const fs::path dir = synthetic("synth-video", o, truth);
  const fs::path avi = dir / "video.avi";
  {
    cv::VideoWriter w(avi.string(), cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 10, cv::Size(o.width, o.height), false);
    ASSERT_TRUE(w.isOpened());
    for (const auto& f : truth.frames) w.write(cv::imread(f, cv::IMREAD_GRAYSCALE));
  }
  FrameSource all(avi.string());
  cv::Mat f;
  int index = 0, n = 0;
  while (all.next(f, index)) ++n;
  EXPECT_EQ(n, 12);
  FrameSource part(avi.string(), cv::Rect(10, 20, 100, 50), FrameRange{2, 9, 3});
  std::vector<int> seen;
  while (part.next(f, index)) {
    seen.push_back(index);
    EXPECT_EQ(f.cols, 100);
    EXPECT_EQ(f.rows, 50);
  }
  EXPECT_EQ(seen, (std::vector<int>{2, 5, 8}));
  // The same frames from the PNG folder and from the video agree up to JPEG loss.
  FrameSource png((dir / "frames").string()), vid(avi.string());
  cv::Mat a, b;
  png.next(a, index);
  vid.next(b, index);
  EXPECT_LT(cv::norm(a, b, cv::NORM_L1) / a.total(), 0.02);
}

TEST(Frames, BadInputsAreNamed) {
  const fs::path d = fs::path(MMVAL_BINARY_DIR) / "test-output" / "bad-frames";
  fs::remove_all(d);
  fs::create_directories(d / "empty");
  EXPECT_THROW(FrameSource((d / "empty").string()), InputError);
  fs::create_directories(d / "sizes");
  cv::imwrite((d / "sizes" / "a.png").string(), cv::Mat(20, 30, CV_8U, cv::Scalar(100)));
  cv::imwrite((d / "sizes" / "b.png").string(), cv::Mat(25, 30, CV_8U, cv::Scalar(100)));
  FrameSource sizes((d / "sizes").string());
  cv::Mat f;
  int i = 0;
  EXPECT_TRUE(sizes.next(f, i));
  try {
    sizes.next(f, i);
    FAIL() << "expected a size error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("b.png"), std::string::npos) << e.what();
  }
  std::ofstream(d / "broken.avi") << "not a video at all";
  EXPECT_THROW(FrameSource((d / "broken.avi").string()), InputError);
  EXPECT_THROW(FrameSource((d / "none*.png").string()), InputError);
  // Blank frames: no particles, no crash, no NaN.
  fs::create_directories(d / "blank");
  for (int k = 0; k < 3; ++k) cv::imwrite((d / "blank" / ("f" + std::to_string(k) + ".png")).string(), cv::Mat(40, 40, CV_8U, cv::Scalar(128)));
  FrameSource blank((d / "blank").string());
  const TrackRun run = runTracker(blank, TrackConfig{}, true);
  EXPECT_TRUE(run.tracks.points.empty());
}

}  // namespace
}  // namespace mmval::tracking
