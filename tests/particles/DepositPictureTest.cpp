// deposits.png (MicromodelPicture.hpp): grains, paths and retained particles drawn where the
// trajectories put them.
#include <gtest/gtest.h>

#include <filesystem>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "MicromodelPicture.hpp"

namespace mmval::particles {
namespace {

namespace fs = std::filesystem;

/// A trajectory row in pixel columns only (the picture reads nothing else).
TrackPoint row(std::int64_t particle, std::int64_t frame, double x_px, double y_px, const char* state) {
  TrackPoint p;
  p.particle = particle, p.frame = frame, p.state = state;
  p.x_px = x_px, p.y_px = y_px;
  return p;
}

TEST(DepositPicture, GrainsPathsAndRetainedParticlesAreWhereTheFilesPutThem) {
  // 100 x 60 px chip, a grain block at columns 40-59, rows 0-19; scale 12 (1200 / 100).
  PixelMask grains = PixelMask::Constant(60, 100, false);
  grains.block(0, 40, 20, 20).setConstant(true);
  Tracks t;
  // Particle 1 crosses the chip along row 40 and leaves; particle 2 stops at (70, 25), 2 px radius.
  for (int f = 0; f <= 10; ++f) t.points.push_back(row(1, f, 10.0 * f, 40.0, "mobile"));
  for (int f = 0; f <= 5; ++f) t.points.push_back(row(2, f, 10.0 + 12.0 * f, 25.0, f == 5 ? "deposited" : "mobile"));
  const fs::path file = fs::temp_directory_path() / "mmval-deposits-picture.png";
  const DepositPictureCounts n = writeDepositPicture(file, grains, t, 2.0);
  EXPECT_EQ(n.particles, 2);
  EXPECT_EQ(n.paths, 2);
  EXPECT_EQ(n.retained, 1);
  const cv::Mat img = cv::imread(file.string(), cv::IMREAD_COLOR);
  ASSERT_EQ(img.cols, 1200);
  ASSERT_EQ(img.rows, 720);
  // Pixel (c, r) of the mask covers picture pixels [12c, 12c + 12); x_px = c is that block's centre.
  const auto px = [&](double x_px, double y_px) { return img.at<cv::Vec3b>(static_cast<int>((y_px + 0.5) * 12), static_cast<int>((x_px + 0.5) * 12)); };
  const cv::Vec3b grain = px(50, 15), pore = px(20, 50), path = px(55, 40), retained = px(70, 25);
  EXPECT_EQ(grain, cv::Vec3b(128, 128, 128));
  EXPECT_EQ(pore, cv::Vec3b(250, 250, 250));
  EXPECT_GT(path[0], path[2] + 100) << "blue (BGR) on the moving particle's path";
  EXPECT_GT(retained[2], retained[0] + 150) << "red (BGR) where the retained particle stopped";
  // The red disc has the particle's radius: 2 px = 24 picture px, so red 20 px from its centre and not 30.
  const auto redAt = [&](int dx) { const cv::Vec3b v = img.at<cv::Vec3b>(static_cast<int>(25.5 * 12), static_cast<int>(70.5 * 12) + dx); return v[2] > v[0] + 150; };
  EXPECT_TRUE(redAt(20));
  EXPECT_FALSE(redAt(30));
  fs::remove(file);
}

}  // namespace
}  // namespace mmval::particles
