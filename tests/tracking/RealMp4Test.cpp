// A real camera video (H.264 mp4) tracked as a user would: `mmval track` on the hydrogel
// video of the shared data (a dense, slowly moving packing of dark round particles ~27 px
// across, ~30 px apart; particletracker-videos/PROVENANCE.md beside it), with one
// documented size setting, against a count made by hand.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <nlohmann/json.hpp>

#include "../apps/RunMmval.hpp"
#include "DetectionCounts.hpp"

namespace mmval::tracking {
namespace {

namespace fs = std::filesystem;
using mmval::test::freshTestFolder;
using mmval::test::countInRegion;
using mmval::test::runMmval;

const fs::path kVideos = fs::path(MMVAL_SHARED_DATA_DIR) / "particletracker-videos";

TEST(TrackingRealMp4, HydrogelPackingCountMatchesAHandCount) {
  if (!fs::exists(kVideos / "hydrogel.mp4")) GTEST_SKIP() << "no shared data at " << kVideos;
  const fs::path out = freshTestFolder("real-mp4", "hydrogel");
  // The one setting: the particles' size, as trackpy's diameter (docs/trackpy-mapping.md).
  // 25 px, not the ~27 px the particles measure: --diameter also sets the separation
  // (diameter + 1), which must stay below the packing's nearest-neighbour distance (~30 px)
  // or every other neighbour is suppressed (diameter 29 found 432 per frame, about half).
  // Polarity is left to mmval: with no background subtracted it judges dark from the frames.
  const auto track = runMmval("track " + (kVideos / "hydrogel.mp4").string() + " --diameter 25 --pixel-size-um 1 --fps 30 --quiet --out " +
                              (out / "track").string());
  ASSERT_EQ(track.status, 0) << track.output;
  std::ifstream summary_file(out / "track" / "summary.json");
  const auto summary = nlohmann::json::parse(summary_file);
  EXPECT_EQ(summary.at("detection").at("polarity"), "dark") << summary.at("detection").dump(2);
  // Hand count (frame 10, decoded to PNG and viewed at 2x with a 50-px grid): in the
  // region x 600-850, y 300-500 px, 53 particles have their centre inside (50 clearly
  // seen, 3 faint or defocused ones among them; the packing's lattice, ~37 px along a row
  // and ~24 px between rows, gives ~57 for that area). Tolerance 5 (10 %): +-2 for
  // particles on the region's edges that a person may count either way, +3 for the faint
  // ones a detector may miss.
  constexpr int kHandCount = 53, kTolerance = 5;
  const auto counts = countInRegion(out / "track" / "detections.csv", 600, 300, 850, 500);
  ASSERT_EQ(counts.size(), 50u);  // every frame of the video
  std::vector<int> v;
  for (const auto& [frame, n] : counts) v.push_back(n);
  std::sort(v.begin(), v.end());
  const int median = v[v.size() / 2];
  std::printf("hydrogel.mp4, region 600-850 x 300-500 px: median %d per frame (min %d, max %d), hand count %d\n", median, v.front(), v.back(), kHandCount);
  EXPECT_NEAR(median, kHandCount, kTolerance);
  // Stable: the packing moves slowly, so the count changes only as particles cross the
  // region's edges (a few per frame): range at most 6 (before: 2-943 per frame over the
  // whole frame with the median background).
  EXPECT_LE(v.back() - v.front(), 6);
}

}  // namespace
}  // namespace mmval::tracking
