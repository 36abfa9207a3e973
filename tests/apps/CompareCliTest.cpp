// `mmval compare` as a user meets it: ids above 2^53 stay apart,
// degenerate tracks files exit 2 naming file, column and value, and a failed
// metric exits 3 after the outputs are written.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "RunMmval.hpp"

#include <sys/wait.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

using mmval::test::Outcome;

Outcome mmval(const std::string& args) { return mmval::test::runMmval(args); }

fs::path scratch(const std::string& name) { return mmval::test::freshTestFolder("cli-compare", name); }

/// Particles `ids` moving along x at `speed_um_s` x 1, 2, 3 ..., 20 frames 0.1 s apart, 100 um apart in y.
std::string movingRows(const std::vector<std::int64_t>& ids, double speed_um_s) {
  std::string rows = "frame,particle,t_s,x_um,y_um\n";
  for (std::size_t i = 0; i < ids.size(); ++i)
    for (int f = 0; f < 20; ++f) rows += fmt::format("{},{},{:.1f},{:g},{:g}\n", f, ids[i], 0.1 * f, speed_um_s * (i + 1) * 0.1 * f, 100.0 * i);
  return rows;
}

/// `mmval compare` of the two CSV texts in folder `d`.
Outcome compareTexts(const fs::path& d, const std::string& experiment, const std::string& simulation) {
  std::ofstream(d / "exp.csv") << experiment;
  std::ofstream(d / "sim.csv") << simulation;
  return mmval(fmt::format("compare --experiment {} --simulation {} --out {}", (d / "exp.csv").string(), (d / "sim.csv").string(), (d / "out").string()));
}

double metricValue(const fs::path& metrics_json, const std::string& name) {
  std::ifstream in(metrics_json);
  const auto j = nlohmann::json::parse(in);
  for (const auto& m : j["metrics"])
    if (m["name"] == name) return m["value"].get<double>();
  ADD_FAILURE() << "no metric " << name;
  return 0;
}

constexpr std::int64_t kTwoTo53 = std::int64_t{1} << 53;

TEST(CompareCli, ParticleIdsAbove2To53KeepTheirOwnTracks) {
  const fs::path d = scratch("big-ids");
  // 20, 40, 60 um/s: mean 40 um/s in both files (merged ids gave thousands in the experiment).
  const Outcome o = compareTexts(d, movingRows({kTwoTo53, kTwoTo53 + 1, kTwoTo53 + 2}, 20), movingRows({1, 2, 3}, 20));
  EXPECT_EQ(o.status, 0) << o.output;
  ASSERT_TRUE(fs::exists(d / "out" / "metrics.json")) << o.output;
  EXPECT_NEAR(metricValue(d / "out" / "metrics.json", "mean_speed"), 40.0, 1e-6);
  std::ifstream in(d / "out" / "metrics.json");
  const auto j = nlohmann::json::parse(in);
  EXPECT_EQ(j["experiment"]["particles"].get<int>(), 3);
}

TEST(CompareCli, HeaderOnlyFileExitsTwoNamingTheFile) {
  const fs::path d = scratch("header-only");
  const Outcome o = compareTexts(d, "frame,particle,t_s,x_um,y_um\n", movingRows({1, 2}, 20));
  EXPECT_EQ(o.status, 2) << o.output;
  EXPECT_THAT(o.output, HasSubstr((d / "exp.csv").string() + ": no track rows: the file has only its header; got 0 rows"));
  EXPECT_FALSE(fs::exists(d / "out"));
}

TEST(CompareCli, OneRowFileExitsTwo) {
  const fs::path d = scratch("one-row");
  const Outcome o = compareTexts(d, movingRows({1, 2}, 20), "frame,particle,t_s,x_um,y_um\n0,1,0,5,5\n");
  EXPECT_EQ(o.status, 2) << o.output;
  EXPECT_THAT(o.output, HasSubstr((d / "sim.csv").string() + ": key 'particle': every particle has a single row"));
}

TEST(CompareCli, AllEqualTimeExitsTwoNamingTheValue) {
  const fs::path d = scratch("equal-time");
  std::string rows = "frame,particle,t_s,x_um,y_um\n";
  for (int f = 0; f < 10; ++f) rows += fmt::format("{},1,0.5,{},0\n{},2,0.5,{},50\n", f, 3 * f, f, 2 * f);
  const Outcome o = compareTexts(d, rows, movingRows({1, 2}, 20));
  EXPECT_EQ(o.status, 2) << o.output;
  EXPECT_THAT(o.output, HasSubstr("key 't_s': time does not advance within any particle; got t_s = 0.5 s in every row"));
}

TEST(CompareCli, NegativeFrameExitsTwoNamingLineAndValue) {
  const fs::path d = scratch("negative-frame");
  const Outcome o = compareTexts(d, "frame,particle,t_s,x_um,y_um\n0,1,0,0,0\n-1,1,0.1,1,0\n", movingRows({1, 2}, 20));
  EXPECT_EQ(o.status, 2) << o.output;
  EXPECT_THAT(o.output, HasSubstr((d / "exp.csv").string() + ":3:1: key 'frame': negative frame index; got -1"));
}

TEST(CompareCli, FailedMetricExitsThreeAfterWritingOutputs) {
  const fs::path d = scratch("fail");
  // The simulation moves twice as fast: mean and median speed are 100 % off (tolerance 20 %).
  const Outcome o = compareTexts(d, movingRows({1, 2, 3}, 20), movingRows({1, 2, 3}, 40));
  EXPECT_EQ(o.status, 3) << o.output;
  EXPECT_THAT(o.output, HasSubstr("outside tolerance: mean_speed, median_speed"));
  ASSERT_TRUE(fs::exists(d / "out" / "metrics.json"));
  std::ifstream in(d / "out" / "metrics.json");
  EXPECT_FALSE(nlohmann::json::parse(in)["all_pass"].get<bool>());
  EXPECT_NEAR(metricValue(d / "out" / "metrics.json", "mean_speed"), 80.0, 1e-6);
}

/// The rows of movingRows as trackpy saves a linked DataFrame (index column, y before x,
/// frame and particle; pixels of 0.5 um, frames 0.1 s apart).
std::string trackpyRows(const std::vector<std::int64_t>& ids, double speed_um_s) {
  std::string rows = ",y,x,mass,frame,particle\n";
  int index = 0;
  for (std::size_t i = 0; i < ids.size(); ++i)
    for (int f = 0; f < 20; ++f) rows += fmt::format("{},{:g},{:g},120.5,{},{}\n", index++, 100.0 * i / 0.5, speed_um_s * (i + 1) * 0.1 * f / 0.5, f, ids[i]);
  return rows;
}

/// The rows of movingRows as TrackMate 7 exports its Spots table (keys, names, short names, units).
std::string trackmateRows(const std::vector<std::int64_t>& ids, double speed_um_s) {
  std::string rows =
      "LABEL,ID,TRACK_ID,QUALITY,POSITION_X,POSITION_Y,POSITION_Z,POSITION_T,FRAME\n"
      "Label,Spot ID,Track ID,Quality,X,Y,Z,T,Frame\nLabel,Spot ID,Track ID,Quality,X,Y,Z,T,Frame\n"
      ",,,(quality),(micron),(micron),(micron),(sec),\n";
  int spot = 0;
  for (std::size_t i = 0; i < ids.size(); ++i)
    for (int f = 0; f < 20; ++f, ++spot)
      rows += fmt::format("ID{},{},{},1.0,{:g},{:g},0,{:.1f},{}\n", spot, spot, ids[i], speed_um_s * (i + 1) * 0.1 * f, 100.0 * i, 0.1 * f, f);
  return rows;
}

TEST(CompareCli, TrackpyAndTrackmateFilesCompareLikeMmvalsOwn) {
  const fs::path d = scratch("foreign");
  std::ofstream(d / "exp-trackpy.csv") << trackpyRows({1, 2, 3}, 20);
  std::ofstream(d / "sim-trackmate.csv") << trackmateRows({7, 8, 9}, 20);
  const Outcome o = mmval(fmt::format("compare --experiment {} --simulation {} --fps 10 --pixel-size-um 0.5 --out {}", (d / "exp-trackpy.csv").string(),
                                      (d / "sim-trackmate.csv").string(), (d / "out").string()));
  EXPECT_EQ(o.status, 0) << o.output;
  EXPECT_THAT(o.output, HasSubstr("trackpy tracks"));
  EXPECT_THAT(o.output, HasSubstr("TrackMate spots"));
  ASSERT_TRUE(fs::exists(d / "out" / "metrics.json")) << o.output;
  // The same motion in mmval's own schema gives the same metrics.
  const fs::path ref = scratch("foreign-reference");
  const Outcome r = compareTexts(ref, movingRows({1, 2, 3}, 20), movingRows({7, 8, 9}, 20));
  ASSERT_EQ(r.status, 0) << r.output;
  for (const char* metric : {"mean_speed", "median_speed"})
    EXPECT_NEAR(metricValue(d / "out" / "metrics.json", metric), metricValue(ref / "out" / "metrics.json", metric), 1e-9) << metric;
  EXPECT_NEAR(metricValue(d / "out" / "metrics.json", "mean_speed"), 40.0, 1e-6);
  // trackpy without a frame rate: exit 2 naming the flag.
  const Outcome no_fps = mmval(fmt::format("compare --experiment {} --simulation {} --pixel-size-um 0.5 --out {}", (d / "exp-trackpy.csv").string(),
                                           (d / "sim-trackmate.csv").string(), (d / "out2").string()));
  EXPECT_EQ(no_fps.status, 2) << no_fps.output;
  EXPECT_THAT(no_fps.output, HasSubstr("--fps"));
}

/// movingRows, except that the last particle stops after frame 9 and rests for the last 1 s (10 frames).
std::string restingRows(const std::vector<std::int64_t>& ids, double speed_um_s) {
  std::string rows = "frame,particle,t_s,x_um,y_um\n";
  for (std::size_t i = 0; i < ids.size(); ++i)
    for (int f = 0; f < 20; ++f) {
      const int moved = i + 1 == ids.size() ? std::min(f, 9) : f;
      rows += fmt::format("{},{},{:.1f},{:g},{:g}\n", f, ids[i], 0.1 * f, speed_um_s * (i + 1) * 0.1 * moved, 100.0 * i);
    }
  return rows;
}

TEST(CompareCli, RestRuleFlagsDecideWhichStepsAreMotion) {
  // Steps of 20 and 40 um/s (19 each) and 60 um/s (9), then 10 steps at rest: the mean over steps
  // is 1680 / 57 um/s with the rest counted as motion, 1680 / 47 um/s with it left out.
  const fs::path d = scratch("rest-rule");
  const std::string rows = restingRows({1, 2, 3}, 20);
  std::ofstream(d / "exp.csv") << rows;
  std::ofstream(d / "sim.csv") << rows;
  const auto run = [&](const std::string& flags, const std::string& out) {
    const Outcome o = mmval(fmt::format("compare --experiment {} --simulation {} --out {} {}", (d / "exp.csv").string(), (d / "sim.csv").string(),
                                        (d / out).string(), flags));
    EXPECT_EQ(o.status, 0) << o.output;
    return o;
  };
  const Outcome off = run("--rest-window-s 0", "off");
  EXPECT_NEAR(metricValue(d / "off" / "metrics.json", "mean_speed"), 1680.0 / 57, 1e-6);
  // The default window (the tracker's 2 s) is longer than the 1-s rest: the same as no rule.
  run("", "default");
  EXPECT_NEAR(metricValue(d / "default" / "metrics.json", "mean_speed"), 1680.0 / 57, 1e-6);
  const Outcome half = run("--rest-window-s 0.5 --rest-um 1", "half");
  EXPECT_NEAR(metricValue(d / "half" / "metrics.json", "mean_speed"), 1680.0 / 47, 1e-6);
  // The 11 resting points (frames 9-19 of the last particle) are reported for each file.
  EXPECT_THAT(half.output, HasSubstr("experiment 11 of 60 points at rest, simulation 11 of 60"));
  EXPECT_THAT(off.output, HasSubstr("experiment 0 of 60 points at rest"));
  // A negative window is a usage error (exit 1, README) naming the flag and what it expects.
  const Outcome bad = mmval(fmt::format("compare --experiment {} --simulation {} --out {} --rest-window-s -1", (d / "exp.csv").string(),
                                        (d / "sim.csv").string(), (d / "bad").string()));
  EXPECT_EQ(bad.status, 1) << bad.output;
  EXPECT_THAT(bad.output, HasSubstr("--rest-window-s: expected a non-negative number of seconds, got -1"));
}

}  // namespace
