// `mmval sweep`: the axes as the command line gives them, the statistics it
// reports (checked against the runs' own result.json files and against a
// plain `mmval run` of the same setting), resume, and the input errors.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "../ResultJson.hpp"
#include "RunMmval.hpp"
#include "mmval/validate/Sweep.hpp"
#include "mmval/core/Error.hpp"

namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

using mmval::test::metricOf;
using mmval::test::readJson;

const std::string kChannel = std::string(MMVAL_SOURCE_DIR) + "/cases/particles-channel.toml";
// A small channel scene (about 0.5 s a run): 40 fines, 4 s.
const std::string kSmall = " --set particles.count=40 --set 'run.duration=\"4 s\"' --set 'particles.injection_time=\"2 s\"' --quiet";

TEST(SweepAxis, ValuesSplitAtTopLevelCommasOnly) {
  const auto a = mmval::validate::parseSweepAxis(R"(chemistry.ionic_strength="1 mol/m3","10 mol/m3, as written",[1, 2])");
  EXPECT_EQ(a.key, "chemistry.ionic_strength");
  ASSERT_EQ(a.values.size(), 3u);
  EXPECT_EQ(a.values[0], "\"1 mol/m3\"");
  EXPECT_EQ(a.values[1], "\"10 mol/m3, as written\"");
  EXPECT_EQ(a.values[2], "[1, 2]");
  EXPECT_EQ(mmval::validate::parseSweepAxis("numerics.cells_per_pixel = 0.5, 1 ,2").values, (std::vector<std::string>{"0.5", "1", "2"}));
}

TEST(SweepAxis, MalformedAxesAreInputErrorsNamingVary) {
  for (const char* bad : {"numerics.cells", "=1,2", "a..b=1", "k=1,,2", "k=\"open,2", "k=[1,2", "k=1,1"}) {
    try {
      mmval::validate::parseSweepAxis(bad);
      ADD_FAILURE() << bad << " was accepted";
    } catch (const mmval::InputError& e) {
      EXPECT_THAT(std::string(e.what()), HasSubstr("--")) << bad;
    }
  }
}

TEST(SweepStats, MeanDeviationAndStandardErrorOfASample) {
  // {1, 2, 3, 6}: mean 3, sample variance (4 + 1 + 0 + 9) / 3 = 14/3.
  const auto s = mmval::validate::sampleStats({1, 2, std::nan(""), 3, 6});
  EXPECT_EQ(s.n, 4);
  EXPECT_DOUBLE_EQ(s.mean, 3.0);
  EXPECT_NEAR(s.sd, std::sqrt(14.0 / 3.0), 1e-14);
  EXPECT_NEAR(s.se, std::sqrt(14.0 / 3.0) / 2.0, 1e-14);
  EXPECT_DOUBLE_EQ(s.min, 1.0);
  EXPECT_DOUBLE_EQ(s.max, 6.0);
  EXPECT_EQ(mmval::validate::sampleStats({}).n, 0);
}

TEST(Sweep, StatisticsAreThoseOfItsRunsAndARunIsThePlainRunOfItsSetting) {
  const fs::path dir = mmval::test::freshTestFolder("sweep", "channel");
  const std::string args = "sweep " + kChannel + kSmall + " --vary 'channel.mean_velocity=\"0.36 mm/s\",\"0.72 mm/s\"' --seeds 3" +
                           " --metric retained_fraction --out " + (dir / "sw").string();
  const auto o = mmval::test::runMmval(args);
  ASSERT_EQ(o.status, 0) << o.output;
  EXPECT_THAT(o.output, HasSubstr("6 run(s)"));
  const nlohmann::json sw = readJson(dir / "sw" / "sweep.json");
  ASSERT_EQ(sw.at("groups").size(), 2u);
  // Setting 2 (0.72 mm/s) holds runs 4-6 (seeds 1-3): its statistics recomputed from their result.json files.
  std::vector<double> v;
  for (const char* run : {"run-004", "run-005", "run-006"}) v.push_back(metricOf(readJson(dir / "sw" / "runs" / run / "result.json"), "retained_fraction"));
  const double mean = (v[0] + v[1] + v[2]) / 3;
  const double sd = std::sqrt(((v[0] - mean) * (v[0] - mean) + (v[1] - mean) * (v[1] - mean) + (v[2] - mean) * (v[2] - mean)) / 2);
  const auto& g = sw.at("groups")[1];
  EXPECT_EQ(g.at("setting").at("channel.mean_velocity"), "0.72 mm/s");
  EXPECT_NEAR(g.at("metrics").at("retained_fraction").at("mean").get<double>(), mean, 1e-12);
  EXPECT_NEAR(g.at("metrics").at("retained_fraction").at("se").get<double>(), sd / std::sqrt(3.0), 1e-12);
  EXPECT_GT(sd, 0.0) << "three seeds gave the same retention: the seed did not reach the runs";
  // The band spans the two setting means; the velocity's effect is their difference.
  const double m1 = sw.at("groups")[0].at("metrics").at("retained_fraction").at("mean").get<double>();
  EXPECT_NEAR(sw.at("band").at("retained_fraction").at("max_of_means").get<double>(), std::max(m1, mean), 1e-12);
  EXPECT_NEAR(sw.at("effects").at("channel.mean_velocity").at("retained_fraction").get<double>(), std::abs(m1 - mean), 1e-12);
  // Run 5 is `mmval run` with the same settings and seed 2.
  const auto plain = mmval::test::runMmval("run " + kChannel + kSmall + " --set 'channel.mean_velocity=\"0.72 mm/s\"' --set run.seed=2 --out " +
                                           (dir / "plain").string());
  ASSERT_NE(plain.status, 1) << plain.output;
  EXPECT_EQ(metricOf(readJson(dir / "plain" / "result.json"), "retained_fraction"), v[1]);
  // sweep.csv: a header and one row per run.
  std::ifstream csv(dir / "sw" / "sweep.csv");
  std::string line;
  int rows = 0;
  while (std::getline(csv, line)) ++rows;
  EXPECT_EQ(rows, 7);
  // --resume keeps every complete run.
  const auto again = mmval::test::runMmval(args + " --resume");
  ASSERT_EQ(again.status, 0) << again.output;
  EXPECT_THAT(again.output, HasSubstr("kept the complete earlier run"));
  EXPECT_EQ(readJson(dir / "sw" / "sweep.json").at("groups"), sw.at("groups"));
}

TEST(Sweep, BadSweepsStopBeforeAnyRunNamingWhatIsWrong) {
  const fs::path dir = mmval::test::freshTestFolder("sweep", "bad");
  auto o = mmval::test::runMmval("sweep " + kChannel + kSmall + " --vary channel.no_such_key=1,2 --out " + (dir / "a").string());
  EXPECT_EQ(o.status, 2) << o.output;
  EXPECT_THAT(o.output, HasSubstr("no_such_key"));
  EXPECT_FALSE(fs::exists(dir / "a" / "runs"));
  // A deterministic kind has no seed key.
  o = mmval::test::runMmval("sweep " + std::string(MMVAL_SOURCE_DIR) + "/cases/fluid-poiseuille.toml --seeds 3 --out " + (dir / "b").string());
  EXPECT_EQ(o.status, 2) << o.output;
  EXPECT_THAT(o.output, HasSubstr("--seeds"));
  // A folder of the user's is not written into.
  fs::create_directories(dir / "mine");
  std::ofstream(dir / "mine" / "notes.txt") << "mine";
  o = mmval::test::runMmval("sweep " + kChannel + kSmall + " --vary run.seed=1,2 --out " + (dir / "mine").string());
  EXPECT_EQ(o.status, 2) << o.output;
  EXPECT_TRUE(fs::exists(dir / "mine" / "notes.txt"));
  EXPECT_FALSE(fs::exists(dir / "mine" / "runs"));
}

}  // namespace
