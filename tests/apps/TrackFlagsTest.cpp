// `mmval track` with trackpy's parameter names (docs/trackpy-mapping.md): trackpy's own
// settings for its test frames (../shared/data/trackpy-tests, PROVENANCE.md: locate with
// diameter 9, minmass 140, invert; link with search range 5, memory 0) given as flags
// must find trackpy's features; each flag and `--set` refuse bad values naming themselves.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "RunMmval.hpp"
#include "mmval/core/Tracks.hpp"
#include "../NumericCsv.hpp"

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using mmval::test::Outcome;
using mmval::test::runMmval;

namespace {

const fs::path kData = fs::path(MMVAL_SHARED_DATA_DIR) / "trackpy-tests";

std::vector<std::vector<double>> readCsv(const fs::path& p) { return mmval::test::readNumericCsv(p); }

/// Index of our nearest point of `frame` to (x, y) within 1 px, or -1.
int nearestWithin1px(const mmval::Tracks& t, std::int64_t frame, double x, double y) {
  int best = -1;
  double dist = 1.0;
  for (std::size_t i = 0; i < t.points.size(); ++i) {
    const auto& p = t.points[i];
    if (p.frame != frame) continue;
    const double d = std::hypot(p.x_px - x, p.y_px - y);
    if (d < dist) {
      dist = d;
      best = static_cast<int>(i);
    }
  }
  return best;
}

std::string trackpyFlags() { return "--diameter 9 --minmass 140 --invert --search-range 5 --memory 0"; }

TEST(TrackFlags, TrackpySettingsAsFlagsFindTrackpysFeaturesOnItsFrames) {
  ASSERT_TRUE(fs::exists(kData)) << "shared data missing: " << kData;
  const fs::path out = mmval::test::freshTestFolder("track-flags", "trackpy");
  const Outcome o = runMmval(fmt::format("track {} --out {} --pixel-size-um 1 --fps 1 --quiet {}", (kData / "frames").string(), out.string(), trackpyFlags()));
  ASSERT_EQ(o.status, 0) << o.output;
  const mmval::Tracks ours = mmval::readTracksCsv(out / "tracks.csv");
  // The flags set trackpy's locate (result.json records the resolved keys).
  std::ifstream rj(out / "result.json");
  const nlohmann::json result = nlohmann::json::parse(rj);
  const auto& resolved = result.at("resolved_case");
  EXPECT_EQ(resolved["detect"]["refine_radius"], 4);
  EXPECT_EQ(resolved["detect"]["local_background"], 4);
  EXPECT_EQ(resolved["detect"]["separation"], 10);
  EXPECT_EQ(resolved["detect"]["refinement"], "disc");
  EXPECT_EQ(resolved["detect"]["polarity"], "dark");
  EXPECT_NEAR(resolved["detect"]["min_mass_relative"].get<double>(), 140.0 / 255, 1e-12);
  EXPECT_NEAR(resolved["link"]["search_radius"].get<double>(), 5.0, 1e-12);
  EXPECT_EQ(resolved["link"]["memory"], 0);

  // Frame 0 against trackpy's locate on it (344 features, (y, x)): the target is >= 90 %
  // within 1 px; the detector's own peer test (TrackpyPeerTest) finds 343 with settings
  // written in code. The count stays near trackpy's (its minmass, our min_mass_relative).
  const auto ref = readCsv(kData / "reference" / "locate_first_frame_d9_minmass140.csv");
  ASSERT_EQ(ref.size(), 344u);
  int matched = 0;
  for (const auto& r : ref) matched += nearestWithin1px(ours, 0, r[1], r[0]) >= 0;
  std::size_t ours_frame0 = 0;
  for (const auto& p : ours.points) ours_frame0 += p.frame == 0;
  // The quality columns are there for (nearly) every detected point.
  int measured = 0;
  for (const auto& p : ours.points) measured += p.quality.measured();
  std::printf("trackpy flags, frame 0: %d of %zu trackpy features within 1 px (%.1f %%), %zu ours; %d of %zu points with quality\n", matched,
              ref.size(), 100.0 * matched / ref.size(), ours_frame0, measured, ours.points.size());
  EXPECT_GE(matched, static_cast<int>(std::ceil(0.90 * ref.size())));
  EXPECT_LT(ours_frame0, 1.25 * ref.size());
  EXPECT_GT(ours_frame0, 0.9 * ref.size());
  // (a spot with no positive light above its ring, e.g. squeezed between neighbours, stays unmeasured)
  EXPECT_GE(measured, 0.99 * static_cast<double>(ours.points.size()));

  // All five frames in trackpy's linking crop (100 features, (y, x, frame)), and its
  // tracks there (search range 5, memory 0): each trackpy track whose points we all find
  // is one track of ours.
  const auto input = readCsv(kData / "reference" / "link_input.csv");
  const auto ids = readCsv(kData / "reference" / "link_sr5_mem0_ids.csv");
  ASSERT_EQ(input.size(), ids.size());
  int crop_matched = 0;
  std::map<std::int64_t, std::set<std::int64_t>> ours_of_theirs;
  std::set<std::int64_t> incomplete;
  for (std::size_t i = 0; i < input.size(); ++i) {
    const int k = nearestWithin1px(ours, static_cast<std::int64_t>(input[i][2]), input[i][1], input[i][0]);
    const auto id = static_cast<std::int64_t>(ids[i][0]);
    if (k < 0) {
      incomplete.insert(id);
      continue;
    }
    ++crop_matched;
    ours_of_theirs[id].insert(ours.points[k].particle);
  }
  int same = 0, judged = 0;
  for (const auto& [id, mine] : ours_of_theirs) {
    if (incomplete.count(id)) continue;
    ++judged;
    same += mine.size() == 1;
  }
  std::printf("trackpy flags, linking crop: %d of %zu features within 1 px; %d of %d fully found trackpy tracks are one track of ours\n",
              crop_matched, input.size(), same, judged);
  EXPECT_GE(crop_matched, static_cast<int>(std::ceil(0.90 * input.size())));
  EXPECT_GE(judged, 15);  // of trackpy's 21
  EXPECT_GE(same, judged - 1);
}

TEST(TrackFlags, SetTakesAnyKeyOfTheKindAndChecksItAsTheCaseFileWould) {
  const fs::path out = mmval::test::freshTestFolder("track-flags", "set");
  const Outcome o = runMmval(fmt::format("track {} --out {} --pixel-size-um 1 --fps 1 --quiet --last 1 --set link.memory=3 --set detect.max_size_ratio=0 "
                                         "--set detect.polarity=dark --threads 2",
                                         (kData / "frames").string(), out.string()));
  ASSERT_EQ(o.status, 0) << o.output;
  std::ifstream rj(out / "result.json");
  const nlohmann::json resolved = nlohmann::json::parse(rj).at("resolved_case");
  EXPECT_EQ(resolved["link"]["memory"], 3);
  EXPECT_EQ(resolved["detect"]["threads"], 2);
  EXPECT_EQ(resolved["detect"]["polarity"], "dark");
  EXPECT_NEAR(resolved["detect"]["max_size_ratio"].get<double>(), 0.0, 1e-12);
}

TEST(TrackFlags, BadValuesAreInputErrorsNamingTheFlag) {
  const fs::path out = mmval::test::freshTestFolder("track-flags", "errors");
  const std::string base = fmt::format("track {} --out {} --pixel-size-um 1 --fps 1 --quiet ", (kData / "frames").string(), (out / "run").string());
  // (arguments, what the message must name)
  const std::vector<std::pair<std::string, std::vector<std::string>>> cases = {
      {"--diameter 8", {"--diameter", "odd"}},
      {"--diameter 1", {"--diameter", "3 to 101"}},
      {"--diameter nine", {"--diameter"}},
      {"--minmass -1", {"--minmass", ">= 0"}},
      {"--minmass inf", {"--minmass"}},
      {"--separation 0", {"--separation", "px"}},
      {"--search-range 0", {"--search-range", "per frame"}},
      {"--search-range 5px", {"--search-range"}},
      {"--memory 1.5", {"--memory", "whole number"}},
      {"--memory 101", {"--memory"}},
      {"--threads -1", {"--threads", "every core"}},
      {"--set detect.min_snr=abc", {"detect.min_snr", "--set"}},
      {"--set detect.min_snr=-1", {"detect.min_snr"}},
      {"--set detect.nosuch=1", {"detect.nosuch"}},
      {"--set link.memory", {"--set", "KEY=VALUE"}},
      {"--diameter 9 --set detect.refine_radius=3", {"--diameter", "detect.refine_radius"}},
  };
  for (const auto& [args, names] : cases) {
    const Outcome o = runMmval(base + args);
    EXPECT_EQ(o.status, 2) << args << "\n" << o.output;
    for (const auto& n : names) EXPECT_THAT(o.output, HasSubstr(n)) << args;
  }
  // NaN is not a frame rate (Case::set refuses a non-finite number too, behind this check).
  const Outcome nan_fps =
      runMmval(fmt::format("track {} --out {} --pixel-size-um 1 --fps nan --quiet", (kData / "frames").string(), (out / "run-nan").string()));
  EXPECT_EQ(nan_fps.status, 2) << nan_fps.output;
  EXPECT_THAT(nan_fps.output, HasSubstr("--fps"));
  EXPECT_THAT(nan_fps.output, HasSubstr("finite"));
}

}  // namespace
