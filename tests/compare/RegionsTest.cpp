// Pore bodies and throats of a constructed geometry, and speeds per region
// against the speeds the constructed tracks were given.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include <opencv2/imgproc.hpp>

#include "mmval/compare/Compare.hpp"
#include "mmval/compare/Regions.hpp"
#include "TrackPoints.hpp"
#include "mmval/core/Error.hpp"

namespace mmval::compare {
namespace {

using test_support::pt;

/// 400 x 120 px at 2 um: three 60 x 60 px chambers joined by 10 px high
/// channels on the mid-line (rows 55-64), open to the left and right edges.
cv::Mat chambers() {
  cv::Mat m(120, 400, CV_8U, cv::Scalar(0));
  m(cv::Rect(0, 55, 400, 10)).setTo(255);
  for (int x0 : {20, 140, 260}) m(cv::Rect(x0, 30, 60, 60)).setTo(255);
  return m;
}

const MaskFrame kFrame{2e-6, 120, 400, true};

cv::Point2d at(double col, double row) { return kFrame.toMetres({col, row}); }

/// Particles crossing the chamber centres at `body` m/s and the channel
/// mid-lines at `throat` m/s, 11 frames 0.1 s apart, each staying in its region.
Tracks regionTracks(double body, double throat) {
  Tracks t;
  int id = 0;
  auto add = [&](cv::Point2d start, double speed) {
    ++id;
    for (int f = 0; f <= 10; ++f) t.points.push_back(pt(f, id, 0.1 * f, start.x + speed * 0.1 * f, start.y));
  };
  for (double cx : {50.0, 170.0, 290.0}) {
    add(at(cx - 5, 58), body);  // above the channel's line, inside the chamber
    add(at(cx - 5, 45), body);
  }
  for (double cx : {95.0, 215.0, 335.0}) add(at(cx, 59.5), throat);  // 1 s at 40 um/s: 20 px, clear of the chamber mouths
  return t;
}

TEST(Regions, ChambersAreBodiesChannelsAreThroats) {
  const RegionMap map = classifyPoreSpace(chambers(), kFrame);
  // Inscribed diameters: 2 d of the distance transform, d = 30 px at a chamber
  // centre, 5 px on a channel's mid-line (between rows 59 and 60).
  EXPECT_NEAR(map.width_px.at<float>(60, 50), 60.0, 1.0);
  EXPECT_NEAR(map.width_px.at<float>(59, 110), 10.0, 0.5);
  // Median along the medial axis: the channels' 10 px (most of the axis) up to the chambers' 60.
  EXPECT_GE(map.threshold_px, 10.0);
  EXPECT_LT(map.threshold_px, 60.0);
  auto region = [&](double c, double r) { const cv::Point2d p = at(c, r); return map.at(p.x, p.y); };
  EXPECT_EQ(region(50, 60), Region::body);
  EXPECT_EQ(region(50, 40), Region::body);
  EXPECT_EQ(region(110, 59), Region::throat);
  EXPECT_EQ(region(110, 30), Region::grain);
  EXPECT_EQ(map.at(-1e-3, 0), Region::outside);
  EXPECT_THAT(map.rule, ::testing::HasSubstr("median inscribed diameter"));
  // A given threshold: 30 um = 15 px keeps channels throats, 8 um = 4 px makes everything body.
  EXPECT_EQ(classifyPoreSpace(chambers(), kFrame, {30e-6}).label.at<unsigned char>(59, 110), 2);
  EXPECT_EQ(classifyPoreSpace(chambers(), kFrame, {8e-6}).label.at<unsigned char>(59, 110), 1);
  EXPECT_THROW(classifyPoreSpace(cv::Mat(10, 10, CV_8U, cv::Scalar(0)), kFrame), InputError);
}

TEST(Regions, SpeedsPerRegionAreTheConstructedOnes) {
  const RegionMap map = classifyPoreSpace(chambers(), kFrame);
  CompareOptions o;
  o.regions = &map;
  o.tracks.stuck_window = 0.3;
  // Experiment: 10 um/s in chambers, 40 um/s in channels; simulation 12 and 30 um/s.
  const Comparison c = compareTracks(regionTracks(10e-6, 40e-6), regionTracks(12e-6, 30e-6), o);
  ASSERT_TRUE(c.regions_experiment.has_value());
  EXPECT_EQ(c.regions_experiment->body_steps, 60);
  EXPECT_EQ(c.regions_experiment->throat_steps, 30);
  EXPECT_EQ(c.regions_experiment->grain_steps, 0);
  EXPECT_NEAR(c.regions_experiment->body_mean, 10e-6, 1e-15);
  EXPECT_NEAR(c.regions_experiment->throat_mean, 40e-6, 1e-15);
  EXPECT_NEAR(c.regions_simulation->body_mean, 12e-6, 1e-15);
  EXPECT_NEAR(c.regions_simulation->throat_mean, 30e-6, 1e-15);
  auto metric = [&](const std::string& name) {
    const auto it = std::find_if(c.metrics.begin(), c.metrics.end(), [&](const MetricResult& m) { return m.name == name; });
    EXPECT_NE(it, c.metrics.end()) << name;
    return *it;
  };
  const MetricResult body = metric("speed_pore_bodies"), throat = metric("speed_throats");
  EXPECT_NEAR(body.value, 12.0, 1e-9);
  EXPECT_NEAR(body.reference->value, 10.0, 1e-9);
  EXPECT_NEAR(std::abs(body.error), 0.2, 1e-9);
  EXPECT_TRUE(*body.pass);  // 20 % tolerance by default
  EXPECT_NEAR(throat.value, 30.0, 1e-9);
  EXPECT_NEAR(std::abs(throat.error), 0.25, 1e-9);
  EXPECT_FALSE(*throat.pass);
  const auto j = c.toJson();
  EXPECT_NEAR(j["regions"]["speed_pore_bodies_relative_difference"].get<double>(), 0.2, 1e-9);
  EXPECT_NEAR(j["regions"]["speed_throats_relative_difference"].get<double>(), -0.25, 1e-9);
  EXPECT_THAT(j["regions"]["rule"].get<std::string>(), ::testing::HasSubstr("local pore width"));
}

}  // namespace
}  // namespace mmval::compare
