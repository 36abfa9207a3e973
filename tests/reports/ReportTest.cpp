// The report renders: headless Chromium opens it, the screenshot is not
// blank, every image decodes, and the key numbers are in the DOM.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <fmt/format.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "mmval/compare/Compare.hpp"
#include "mmval/reports/Plot.hpp"
#include "mmval/reports/Report.hpp"

namespace mmval::reports {
namespace {

namespace fs = std::filesystem;

Tracks drift(double speed) {
  // Ten particles drifting along x at `speed` with a y offset each; one of them stops halfway.
  Tracks t;
  for (int p = 0; p < 10; ++p)
    for (int f = 0; f < 40; ++f) {
      const int moving = (p == 0) ? std::min(f, 20) : f;
      t.points.push_back({f, p, 0.1 * f, 10e-6 + moving * speed * 0.1, 5e-6 + p * 8e-6});
    }
  return t;
}

std::string run(const std::string& cmd) {
  std::string out;
  FILE* pipe = popen(cmd.c_str(), "r");
  if (pipe == nullptr) return out;
  char buf[4096];
  while (std::fgets(buf, sizeof buf, pipe) != nullptr) out += buf;
  pclose(pipe);
  return out;
}

TEST(Base64, KnownVectors) {
  // RFC 4648 test vectors.
  EXPECT_EQ(base64(""), "");
  EXPECT_EQ(base64("f"), "Zg==");
  EXPECT_EQ(base64("fo"), "Zm8=");
  EXPECT_EQ(base64("foo"), "Zm9v");
  EXPECT_EQ(base64("foobar"), "Zm9vYmFy");
}

TEST(Plot, GnuplotWritesAnSvg) {
  if (!gnuplotAvailable()) GTEST_SKIP() << "gnuplot not installed";
  const std::string svg = renderSvg({"t", "x", "y", true, true, {{"s", {1, 10, 100}, {1, 0.1, 0.01}, "linespoints"}}});
  EXPECT_THAT(svg, ::testing::StartsWith("<svg"));
  EXPECT_THROW(renderSvg({"empty", "x", "y", false, false, {}}), std::runtime_error);
}

TEST(Report, RendersInHeadlessChromium) {
  if (std::system("command -v chromium >/dev/null 2>&1") != 0) GTEST_SKIP() << "chromium not installed";
  const fs::path dir = fs::path(MMVAL_BINARY_DIR) / "test-output" / "report";
  fs::remove_all(dir);
  compare::CompareOptions o;
  o.tracks.time_bins = 8;
  const compare::Comparison c = compare::compareTracks(drift(20e-6), drift(22e-6), o);
  compare::writeComparison(c, dir / "compare" / "drift");
  const ReportInput input = collect({dir});
  ASSERT_EQ(input.comparisons.size(), 1u);
  const int figures = writeReport(input, dir / "report");
  EXPECT_GE(figures, 4);
  const std::string flags = "--headless --no-sandbox --disable-gpu --disable-background-networking --no-first-run";
  const fs::path html = dir / "report" / "index.html";
  run(fmt::format("chromium {} --window-size=1200,1600 --screenshot={} file://{} 2>/dev/null", flags, (dir / "shot.png").string(), html.string()));
  const cv::Mat shot = cv::imread((dir / "shot.png").string(), cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(shot.empty()) << "no screenshot";
  cv::Scalar mean, stddev;
  cv::meanStdDev(shot, mean, stddev);
  EXPECT_GT(stddev[0], 10.0) << "screenshot is blank";
  const std::string dom = run(fmt::format("chromium {} --virtual-time-budget=5000 --dump-dom file://{} 2>/dev/null", flags, html.string()));
  // Every <img> decoded (the page writes the count once loaded).
  EXPECT_THAT(dom, ::testing::HasSubstr("images loaded: 1 of 1"));
  // Key numbers: the mean speeds, 20 and 22 um/s scaled by the stopped particle's share.
  const auto& m = c.metrics.front();
  EXPECT_EQ(m.name, "mean_speed");
  EXPECT_THAT(dom, ::testing::HasSubstr(fmt::format("{:.4g}", m.value)));
  EXPECT_THAT(dom, ::testing::HasSubstr("streamline_iou"));
  EXPECT_THAT(dom, ::testing::HasSubstr("<svg"));
}

}  // namespace
}  // namespace mmval::reports
