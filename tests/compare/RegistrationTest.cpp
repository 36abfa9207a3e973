// Registration of a frame to the geometry mask: a mask warped by a known
// rigid motion is recovered; unrelated pairs fail with a clear message; the
// fitted motion moves tracks into the mask frame exactly.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mmval/compare/Registration.hpp"
#include "mmval/compare/Scene.hpp"
#include "mmval/core/Error.hpp"

namespace mmval::compare {
namespace {

constexpr double kPi = 3.14159265358979323846;

/// A sand-pack-like mask: random round grains (dark) in bright pore space.
cv::Mat grainMask(int cols, int rows, std::uint64_t seed) {
  cv::Mat m(rows, cols, CV_8U, cv::Scalar(255));
  cv::RNG rng(seed);
  for (int i = 0; i < cols * rows / 900; ++i)
    cv::circle(m, {rng.uniform(0, cols), rng.uniform(0, rows)}, rng.uniform(6, 18), cv::Scalar(0), cv::FILLED, cv::LINE_AA);
  return m;
}

/// Frame pixel -> mask pixel: rotation by `deg` about `centre`, then the shift.
cv::Matx23d rigid(double dx, double dy, double deg, cv::Point2d centre) {
  const double a = deg * kPi / 180, c = std::cos(a), s = std::sin(a);
  return {c, -s, centre.x - c * centre.x + s * centre.y + dx, s, c, centre.y - s * centre.x - c * centre.y + dy};
}

cv::Point2d apply(const cv::Matx23d& w, cv::Point2d p) { return {w(0, 0) * p.x + w(0, 1) * p.y + w(0, 2), w(1, 0) * p.x + w(1, 1) * p.y + w(1, 2)}; }

/// The camera's view: frame(u) = mask(W u).
cv::Mat view(const cv::Mat& mask, const cv::Matx23d& w, cv::Size size) {
  cv::Mat f;
  cv::warpAffine(mask, f, cv::Mat(w), size, cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_REFLECT);
  return f;
}

/// Largest distance between where the true and the fitted motion send the frame's corners and centre.
double worstPointError(const cv::Matx23d& truth, const cv::Matx23d& fit, cv::Size size) {
  double worst = 0;
  for (const cv::Point2d p : {cv::Point2d(0, 0), cv::Point2d(size.width - 1, 0), cv::Point2d(0, size.height - 1),
                              cv::Point2d(size.width - 1, size.height - 1), cv::Point2d(0.5 * size.width, 0.5 * size.height)})
    worst = std::max(worst, cv::norm(apply(truth, p) - apply(fit, p)));
  return worst;
}

TEST(Registration, RecoversAKnownShiftAndRotation) {
  const cv::Mat mask = grainMask(400, 320, 7);
  const cv::Point2d centre(199.5, 159.5);
  const cv::Matx23d truth = rigid(7.3, -4.1, 2.5, centre);
  const RegistrationResult r = registerToMask(view(mask, truth, mask.size()), mask);
  const cv::Matx23d fit = r.transform.matrix();
  // Shift at the frame centre and rotation: 0.1 px and 0.05 deg asked; ECC on
  // blurred, anti-aliased edges does far better.
  const cv::Point2d shift = apply(fit, centre) - centre;
  EXPECT_NEAR(shift.x, 7.3, 0.1);
  EXPECT_NEAR(shift.y, -4.1, 0.1);
  EXPECT_NEAR(r.transform.angle_deg, 2.5, 0.05);
  EXPECT_NEAR(r.transform.dx_px, truth(0, 2), 0.1);
  EXPECT_NEAR(r.transform.dy_px, truth(1, 2), 0.1);
  EXPECT_LT(worstPointError(truth, fit, mask.size()), 0.1);
  EXPECT_GT(r.correlation, 0.95);
  EXPECT_FALSE(r.inverted);
  const auto j = r.toJson(2e-6);
  EXPECT_NEAR(j["dx_um"].get<double>(), 2.0 * r.transform.dx_px, 1e-12);
  RecordProperty("shift_error_x_px", std::to_string(shift.x - 7.3));
  RecordProperty("shift_error_y_px", std::to_string(shift.y + 4.1));
  RecordProperty("angle_error_deg", std::to_string(r.transform.angle_deg - 2.5));
}

TEST(Registration, LargeShiftOfAWindowInvertedAndNoisy) {
  // The camera sees a 200 x 160 window 93.6 px right and 57.2 px down of the
  // mask's corner, rotated by -1.5 deg, with grains bright and sensor noise.
  const cv::Mat mask = grainMask(400, 320, 11);
  const cv::Matx23d truth = rigid(93.6, 57.2, -1.5, {0, 0});
  cv::Mat frame = view(mask, truth, {200, 160});
  frame = 255 - frame;
  cv::Mat noise(frame.size(), CV_8S);
  cv::RNG(3).fill(noise, cv::RNG::NORMAL, 0, 12);
  cv::Mat noisy;
  cv::add(frame, noise, noisy, cv::noArray(), CV_8U);
  const RegistrationResult r = registerToMask(noisy, mask);
  EXPECT_TRUE(r.inverted);
  EXPECT_NEAR(r.transform.angle_deg, -1.5, 0.05);
  EXPECT_LT(worstPointError(truth, r.transform.matrix(), frame.size()), 0.15);
}

TEST(Registration, FramePixelsTwiceTheMaskPixels) {
  // Frame pixel = 2 mask pixels (scale fixed from the pixel sizes, not fitted).
  const cv::Mat mask = grainMask(400, 320, 5);
  cv::Matx23d truth = rigid(20.0, 12.0, 1.0, {0, 0});
  for (int i = 0; i < 2; ++i) truth(i, 0) *= 2, truth(i, 1) *= 2;
  cv::Mat frame;
  cv::warpAffine(mask, frame, cv::Mat(truth), {180, 140}, cv::INTER_AREA | cv::WARP_INVERSE_MAP, cv::BORDER_REFLECT);
  const RegistrationResult r = registerToMask(frame, mask, {}, 2.0);
  EXPECT_DOUBLE_EQ(r.transform.scale, 2.0);
  EXPECT_NEAR(r.transform.angle_deg, 1.0, 0.05);
  EXPECT_LT(worstPointError(truth, r.transform.matrix(), frame.size()), 0.3);
}

TEST(Registration, UnrelatedImagesFailWithAClearMessage) {
  const cv::Mat mask = grainMask(200, 160, 7);
  const cv::Mat other = grainMask(200, 160, 99);
  try {
    registerToMask(other, mask);
    FAIL() << "a frame of other pores registered";
  } catch (const RegistrationFailed& e) {
    EXPECT_THAT(std::string(e.what()), ::testing::AnyOf(::testing::HasSubstr("correlation"), ::testing::HasSubstr("did not converge"),
                                                       ::testing::HasSubstr("overlap")));
  }
  EXPECT_THROW(registerToMask(cv::Mat(160, 200, CV_8U, cv::Scalar(128)), mask), RegistrationFailed);
  // Through files the message names both.
  const auto dir = std::filesystem::path(MMVAL_BINARY_DIR) / "test-output" / "registration";
  std::filesystem::create_directories(dir);
  cv::imwrite((dir / "mask.png").string(), mask);
  cv::imwrite((dir / "other.png").string(), other);
  try {
    registerFiles(dir / "other.png", dir / "mask.png");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_THAT(std::string(e.what()), ::testing::HasSubstr("other.png"));
    EXPECT_THAT(std::string(e.what()), ::testing::HasSubstr("mask.png"));
  }
  EXPECT_THROW(registerFiles(dir / "missing.png", dir / "mask.png"), InputError);
}

TEST(Registration, TracksMoveIntoTheMaskFrame) {
  // Mask 100 rows at 2 um per pixel, y up. Frame pixel (10, 20) under a pure
  // shift (5, -3) is mask pixel (15, 17): centre at (15.5 * 2, (100 - 17.5) * 2) um.
  RegistrationResult r;
  r.transform.dx_px = 5;
  r.transform.dy_px = -3;
  const MaskFrame mf{2e-6, 100, 120, true};
  const auto map = FrameToSimulation::fromRegistration(r, mf);
  Tracks t;
  TrackPoint p;
  p.x_px = 10;
  p.y_px = 20;
  t.points.push_back(p);
  const Tracks moved = applyToTracks(t, map);
  EXPECT_NEAR(moved.points[0].x, 31e-6, 1e-15);
  EXPECT_NEAR(moved.points[0].y, 165e-6, 1e-15);
  const cv::Point2d back = mf.toPixels({moved.points[0].x, moved.points[0].y});
  EXPECT_NEAR(back.x, 15, 1e-9);
  EXPECT_NEAR(back.y, 17, 1e-9);
  // The window given directly: origin (100, 200) um, 90 deg, 2 um pixels, y up.
  // Frame +u runs along +y, frame +v (down the rows) along +x.
  const auto w = FrameToSimulation::fromWindow(100e-6, 200e-6, kPi / 2, 2e-6, true);
  Tracks q;
  TrackPoint a, b;
  a.x_px = 10, a.y_px = 0;
  b.x_px = 0, b.y_px = 10;
  q.points = {a, b};
  const Tracks qm = applyToTracks(q, w);
  EXPECT_NEAR(qm.points[0].x, 100e-6, 1e-15);
  EXPECT_NEAR(qm.points[0].y, 220e-6, 1e-15);
  EXPECT_NEAR(qm.points[1].x, 120e-6, 1e-15);
  EXPECT_NEAR(qm.points[1].y, 200e-6, 1e-15);
  // No pixel columns and no frame pixel size: the error names the file.
  Tracks none;
  none.source = "exp.csv";
  TrackPoint n;
  n.x = 1e-6;
  none.points.push_back(n);
  EXPECT_THROW(applyToTracks(none, w), InputError);
  EXPECT_NEAR(applyToTracks(none, w, 1e-6).points[0].y, 202e-6, 1e-15);  // u = 1 px of 2 um along +y
}

TEST(Scene, RegisteredExperimentLandsOnTheSimulation) {
  // Experiment tracks in camera pixels (2 um) of a frame that sees the mask
  // shifted by (7.3, -4.1) px and rotated by 2.5 deg; the simulation's
  // trajectories are the same particles in the mask frame (y up). Registration
  // through files must put one on the other.
  const auto dir = std::filesystem::path(MMVAL_BINARY_DIR) / "test-output" / "registration-scene";
  std::filesystem::create_directories(dir);
  const cv::Mat mask = grainMask(400, 320, 7);
  const cv::Matx23d truth = rigid(7.3, -4.1, 2.5, {199.5, 159.5});
  const cv::Mat frame = view(mask, truth, mask.size());
  cv::imwrite((dir / "mask.png").string(), mask);
  cv::imwrite((dir / "frame.png").string(), frame);
  const MaskFrame mf{2e-6, mask.rows, mask.cols, true};
  Tracks exp, sim;
  cv::RNG rng(1);
  int id = 0;
  while (id < 30) {
    const double u = rng.uniform(40.0, 340.0), v = rng.uniform(40.0, 280.0), speed = rng.uniform(0.5, 2.0);
    bool in_pore = true;
    for (int f = 0; f < 15; ++f) in_pore = in_pore && frame.at<unsigned char>(int(v), int(u + speed * f)) == 255;
    if (!in_pore) continue;
    ++id;
    for (int f = 0; f < 15; ++f) {
      TrackPoint p;
      p.frame = f;
      p.particle = id;
      p.t = 0.1 * f;
      p.x_px = u + speed * f;
      p.y_px = v;
      p.x = p.x_px * 2e-6;
      p.y = p.y_px * 2e-6;
      exp.points.push_back(p);
      const cv::Point2d m = mf.toMetres(apply(truth, {p.x_px, p.y_px}));
      TrackPoint q = p;
      q.x = m.x;
      q.y = m.y;
      sim.points.push_back(q);
    }
  }
  SceneSpec spec;
  spec.mask = dir / "mask.png";
  spec.mask_pixel_size = 2e-6;
  spec.register_frame = dir / "frame.png";
  const Comparison c = compareScene(exp, sim, spec, CompareOptions{});
  EXPECT_NEAR(c.alignment["rotation_deg"].get<double>(), 2.5, 0.05);
  EXPECT_NEAR(c.alignment["frame_pixel_size_um"].get<double>(), 2.0, 1e-9);  // read from the tracks
  EXPECT_LT(c.wasserstein, 0.01e-6);  // speeds survive a rigid motion
  EXPECT_NEAR(c.iou, 1.0, 1e-12);
  ASSERT_TRUE(c.regions_experiment.has_value());
  EXPECT_EQ(c.regions_experiment->grain_steps, 0);
  EXPECT_EQ(c.regions_experiment->body_steps, c.regions_simulation->body_steps);
  EXPECT_EQ(c.regions_experiment->throat_steps, c.regions_simulation->throat_steps);
  // Inconsistent scenes are refused with the file named.
  SceneSpec both = spec;
  both.window = SceneSpec::Window{0, 0, 0, 2e-6};
  EXPECT_THROW(compareScene(exp, sim, both, CompareOptions{}), InputError);
  SceneSpec no_px = spec;
  no_px.mask_pixel_size = 0;
  EXPECT_THROW(compareScene(exp, sim, no_px, CompareOptions{}), InputError);
}

}  // namespace
}  // namespace mmval::compare
