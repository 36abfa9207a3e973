// The mmval executable opens OpenCV's imgcodecs and videoio on first use
// (tracking/lazyio/LazyOpenCvIo.cpp): they are not among its needed libraries, and
// what it reads and writes through them is what the library, linked as usual, gives:
// the built `mmval` writes a 16-bit TIFF folder and an mp4 (imwrite, VideoWriter) and
// tracks them and a multi-page TIFF (imread, VideoCapture, imcount, imreadmulti); its
// detections.csv must equal, byte for byte, the one this test process writes by running
// the tracker in-process on the same files. The tracker's pictures are written by
// its own PNG encoder (PngWriter.hpp): cv::imread reads the same pixels back.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "../apps/RunMmval.hpp"
#include "PngWriter.hpp"
#include "mmval/tracking/Frames.hpp"
#include "mmval/tracking/Pipeline.hpp"

namespace mmval::tracking {
namespace {

namespace fs = std::filesystem;
using mmval::test::freshTestFolder;
using mmval::test::runMmval;

std::string fileText(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

/// detections.csv of the tracker run in this process (OpenCV linked as usual) with the
/// settings `mmval track INPUT --pixel-size-um 0.15 --fps 24 --threads 1` uses.
std::string detectionsInProcess(const std::string& input, const fs::path& out) {
  TrackConfig c;
  c.pixel_size = 0.15e-6;
  c.fps = 24;
  c.threads = 1;
  FrameSource source(input);
  const TrackRun run = runTracker(source, c, true);
  writeTrackOutputs(run, c, out, nlohmann::json::object());
  return fileText(out / "detections.csv");
}

/// detections.csv of the built mmval on `input`.
std::string detectionsOfCommand(const std::string& input, const fs::path& out) {
  const auto r = runMmval("track " + input + " --pixel-size-um 0.15 --fps 24 --threads 1 --quiet --out " + out.string());
  EXPECT_EQ(r.status, 0) << r.output;
  return fileText(out / "detections.csv");
}

std::string synth(const fs::path& out, const std::string& format) {
  const auto r = runMmval("synth --scene brownian-slab --format " + format + " --width 160 --height 120 --frames 6 --particles 40 --out " + out.string());
  EXPECT_EQ(r.status, 0) << r.output;
  return (out / (format == "mp4" ? "video.mp4" : "frames")).string();
}

TEST(LazyOpenCvIo, ExecutableDoesNotNeedTheModulesAtStart) {
  // The dynamic section of the executable, as readelf prints it (binutils).
  const std::string exe = std::string(MMVAL_BINARY_DIR) + "/bin/mmval";
  FILE* pipe = popen(("readelf -d " + exe + " 2>/dev/null").c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string text;
  char buf[4096];
  while (std::fgets(buf, sizeof buf, pipe) != nullptr) text += buf;
  pclose(pipe);
  if (text.find("NEEDED") == std::string::npos) GTEST_SKIP() << "readelf not available";
  EXPECT_NE(text.find("libopencv_core"), std::string::npos) << text;  // the check sees the needed list
  EXPECT_EQ(text.find("libopencv_imgcodecs"), std::string::npos) << text;
  EXPECT_EQ(text.find("libopencv_videoio"), std::string::npos) << text;
}

TEST(LazyOpenCvIo, CommandReadsAndWritesTiffAndMp4AsTheLibraryDoes) {
  const fs::path dir = freshTestFolder("lazy-opencv-io", "formats");
  for (const std::string format : {"tiff16", "mp4"}) {
    const std::string input = synth(dir / format, format);
    ASSERT_TRUE(fs::exists(input)) << input;
    const std::string by_command = detectionsOfCommand(input, dir / (format + "-command"));
    const std::string in_process = detectionsInProcess(input, dir / (format + "-library"));
    EXPECT_GT(std::count(in_process.begin(), in_process.end(), '\n'), 6 * 5) << format;  // a few spots per frame at least
    EXPECT_EQ(by_command, in_process) << format;
  }
  // A multi-page TIFF (imcount, imreadmulti): the 16-bit frames as one file.
  std::vector<cv::Mat> pages;
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir / "tiff16" / "frames")) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  for (const auto& f : files) pages.push_back(cv::imread(f.string(), cv::IMREAD_UNCHANGED));
  const fs::path stack = dir / "stack.tif";
  ASSERT_TRUE(cv::imwritemulti(stack.string(), pages));
  EXPECT_EQ(detectionsOfCommand(stack.string(), dir / "stack-command"), detectionsInProcess(stack.string(), dir / "stack-library"));
}

TEST(PngWriter, ImreadGivesThePixelsBack) {
  // Random pixels (every filter type wins somewhere) and smooth ramps (the predictors
  // matter), in each layout the tracker's pictures use; odd sizes.
  std::mt19937 rng(7);
  for (int channels : {1, 3, 4}) {
    cv::Mat img(37, 53, CV_8UC(channels));
    for (int y = 0; y < img.rows; ++y)
      for (int x = 0; x < img.cols * channels; ++x)
        img.ptr<unsigned char>(y)[x] = static_cast<unsigned char>(y < img.rows / 2 ? rng() : (3 * x + 5 * y) % 256);
    const std::string png = detail::encodePng(img);
    const cv::Mat back = cv::imdecode(std::vector<unsigned char>(png.begin(), png.end()), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(back.type(), img.type()) << channels;
    ASSERT_EQ(back.size(), img.size()) << channels;
    EXPECT_EQ(cv::norm(back, img, cv::NORM_INF), 0.0) << channels;
  }
  EXPECT_THROW(detail::encodePng(cv::Mat(4, 4, CV_16UC1, cv::Scalar(0))), std::invalid_argument);
}

}  // namespace
}  // namespace mmval::tracking
