// `mmval sweep`: the axes as the command line gives them, the statistics it
// reports (checked against the runs' own result.json files and against a
// plain `mmval run` of the same setting), resume, and the input errors; the
// grid / step / seed uncertainty against analytic ladders (a test kind whose
// metric is f0 + a h^2 + b dt + a fixed noise per seed), docs/outputs.md's
// sweep tables against sweep.json, and the report's sweep page.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "../ResultJson.hpp"
#include "RunMmval.hpp"
#include "mmval/validate/Sweep.hpp"
#include "mmval/core/CaseKind.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Resources.hpp"
#include "mmval/reports/Plot.hpp"
#include "mmval/reports/Report.hpp"
#include "mmval/reports/Site.hpp"

namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

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

// A metric checked against two references has two rows in result.json ("retained_fraction (first)",
// "retained_fraction (second)") with one value: the sweep reads it by the metric's own name, so
// `--metric retained_fraction` finds it (it found nothing before).
TEST(Sweep, AMetricCheckedAgainstTwoReferencesIsReadByItsOwnName) {
  const fs::path dir = mmval::test::freshTestFolder("sweep", "labelled");
  std::ifstream in(kChannel);
  std::stringstream text;
  text << in.rdbuf();
  for (const char* label : {"first", "second"})
    text << "[[acceptance]]\nmetric = \"retained_fraction\"\nlabel = \"" << label
         << "\"\nreference = 0.5\ntolerance = \"none\"\nreason = \"shown, not judged: a second reference for the same metric\"\n";
  const fs::path file = dir / "labelled.toml";
  std::ofstream(file) << text.str();
  const auto o = mmval::test::runMmval("sweep " + file.string() + kSmall + " --seeds 2 --metric retained_fraction --out " + (dir / "sw").string());
  ASSERT_EQ(o.status, 0) << o.output;
  EXPECT_THAT(o.output, Not(HasSubstr("no run reported retained_fraction")));
  const nlohmann::json sw = readJson(dir / "sw" / "sweep.json");
  const nlohmann::json r1 = readJson(dir / "sw" / "runs" / "run-001" / "result.json");
  const nlohmann::json r2 = readJson(dir / "sw" / "runs" / "run-002" / "result.json");
  double v1 = std::nan(""), v2 = std::nan("");
  for (const auto& m : r1.at("metrics"))
    if (m.at("name") == "retained_fraction (second)") v1 = m.at("value").get<double>();
  for (const auto& m : r2.at("metrics"))
    if (m.at("name") == "retained_fraction (first)") v2 = m.at("value").get<double>();
  ASSERT_FALSE(std::isnan(v1) || std::isnan(v2)) << "the case's labelled rows are missing";
  EXPECT_NEAR(sw.at("groups")[0].at("metrics").at("retained_fraction").at("mean").get<double>(), 0.5 * (v1 + v2), 1e-12);
  EXPECT_FALSE(sw.at("groups")[0].at("metrics").contains("retained_fraction (first)"));
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
  // Under mpirun, child processes would take the ranks' places: --jobs above 1 is refused.
  o = mmval::test::runMmval("sweep " + kChannel + kSmall + " --seeds 2 --jobs 2 --out " + (dir / "c").string(), "OMPI_COMM_WORLD_SIZE=2 ");
  EXPECT_EQ(o.status, 2) << o.output;
  EXPECT_THAT(o.output, HasSubstr("--jobs"));
  EXPECT_FALSE(fs::exists(dir / "c" / "runs"));
}


// ---- the uncertainty of a sweep ---------------------------------------------

using mmval::validate::discretisationPart;
using mmval::validate::Finer;
using mmval::validate::LadderLevel;
using mmval::validate::sampleStats;

/// A level whose mean is `mean` with standard error `se` over 5 seeds.
LadderLevel level(double value, double mean, double se) {
  mmval::validate::SampleStats s;
  s.n = 5;
  s.mean = mean;
  s.se = se;
  s.sd = se * std::sqrt(5.0);
  return {value, s, {}};
}

TEST(SweepUncertainty, RichardsonOfAnAnalyticLadderGivesItsOrderAndLimit) {
  // f = f0 + a h^2 with h = 1 / cells_per_pixel: order 2, the limit f0, and the finest level's
  // error a h1^2 (exact algebra: round-off tolerances).
  const double f0 = 0.15, a = 0.08;
  const auto f = [&](double cpp) { return f0 + a / (cpp * cpp); };
  auto p = discretisationPart({level(0.5, f(0.5), 1e-4), level(2, f(2), 1e-4), level(1, f(1), 1e-4)}, Finer::larger);
  EXPECT_EQ(p.method, "richardson") << p.note;
  EXPECT_NEAR(p.observed_order, 2.0, 1e-12);
  EXPECT_NEAR(p.extrapolated, f0, 1e-12);
  EXPECT_NEAR(p.part, a / 4, 1e-12);
  EXPECT_NEAR(p.difference, f(2) - f(1), 1e-15);
  EXPECT_NEAR(p.difference_se, std::sqrt(2.0) * 1e-4, 1e-15);
  EXPECT_DOUBLE_EQ(p.levels.front().value, 2.0) << "finest first";
  // Unequal ratios (1, 2, 3 cells per pixel: r = 1.5 and 2) need Celik's iteration; still order 2.
  p = discretisationPart({level(1, f(1), 1e-4), level(2, f(2), 1e-4), level(3, f(3), 1e-4)}, Finer::larger);
  EXPECT_EQ(p.method, "richardson") << p.note;
  EXPECT_NEAR(p.observed_order, 2.0, 1e-9);
  EXPECT_NEAR(p.extrapolated, f0, 1e-12);
  // A step axis (finer: smaller) of a first-order scheme f = f0 + b dt: order 1.
  const auto g = [&](double dt) { return f0 + 0.3 * dt; };
  p = discretisationPart({level(0.4, g(0.4), 1e-4), level(0.2, g(0.2), 1e-4), level(0.1, g(0.1), 1e-4)}, Finer::smaller);
  EXPECT_EQ(p.method, "richardson") << p.note;
  EXPECT_NEAR(p.observed_order, 1.0, 1e-12);
  EXPECT_NEAR(p.extrapolated, f0, 1e-12);
  EXPECT_NEAR(p.part, 0.3 * 0.1, 1e-12);
}

TEST(SweepUncertainty, FallsBackToTheDifferenceAndSaysWhy) {
  // Not monotone: 0.20, 0.10, 0.12 (coarse to fine).
  auto p = discretisationPart({level(0.5, 0.20, 1e-3), level(1, 0.10, 1e-3), level(2, 0.12, 1e-3)}, Finer::larger);
  EXPECT_EQ(p.method, "difference");
  EXPECT_THAT(p.note, HasSubstr("not monotone"));
  EXPECT_NEAR(p.part, 0.02, 1e-12);
  EXPECT_TRUE(p.resolved);
  // Monotone but the finest difference (0.004) is within 2 standard errors (2 x 0.0042).
  p = discretisationPart({level(0.5, 0.20, 3e-3), level(1, 0.154, 3e-3), level(2, 0.150, 3e-3)}, Finer::larger);
  EXPECT_EQ(p.method, "difference");
  EXPECT_FALSE(p.resolved);
  EXPECT_THAT(p.note, HasSubstr("within 2 standard errors"));
  EXPECT_NEAR(p.part, 0.004, 1e-12);
  // Two levels; a level without a value (n = 0) is left out.
  mmval::validate::SampleStats none;
  p = discretisationPart({level(1, 0.3, 0), {0.5, none, {}}, level(2, 0.31, 0)}, Finer::larger);
  EXPECT_EQ(p.method, "difference");
  EXPECT_EQ(p.levels.size(), 2u);
  EXPECT_NEAR(p.difference, 0.01, 1e-12);
  EXPECT_EQ(discretisationPart({level(1, 0.3, 0)}, Finer::larger).method, "none");
}

TEST(SweepUncertainty, CombinedIsTheRootSumSquareAndTheVerdictReadsBothAxes) {
  const auto seeds = sampleStats({0.10, 0.12, 0.14, 0.11, 0.13});
  auto grid = discretisationPart({level(1, 0.15, 0.005), level(2, 0.14, 0.005)}, Finer::larger);    // part 0.01
  auto step = discretisationPart({level(0.5, 0.125, 0.005), level(0.25, 0.12, 0.005)}, Finer::smaller);  // part 0.005
  auto u = mmval::validate::metricUncertainty(seeds, grid, step, 0.02);
  EXPECT_NEAR(u.seed_se, seeds.se, 1e-15);
  EXPECT_NEAR(u.combined, std::sqrt(seeds.se * seeds.se + 0.01 * 0.01 + 0.005 * 0.005), 1e-14);
  ASSERT_TRUE(u.converged.has_value());
  EXPECT_TRUE(*u.converged);
  EXPECT_FALSE(*u.converged_2se) << "grid part 0.01 + 2 x 0.0071 is beyond 0.02: " << u.verdict;
  u = mmval::validate::metricUncertainty(seeds, grid, step, 0.008);
  EXPECT_FALSE(*u.converged);
  EXPECT_THAT(u.verdict, HasSubstr("NOT converged"));
  EXPECT_THAT(u.verdict, HasSubstr("grid part"));
  u = mmval::validate::metricUncertainty(seeds, std::nullopt, std::nullopt, NAN);
  EXPECT_NEAR(u.combined, seeds.se, 1e-15);
  EXPECT_FALSE(u.converged.has_value());
}

LadderLevel seededLevel(double value, const std::vector<double>& by_seed) { return {value, sampleStats(by_seed), by_seed}; }

TEST(SweepUncertainty, PairedSeedsGiveTheStandardErrorOfTheirDifferences) {
  // Three seeds, finest level {1, 4, 7}, next {0, 2, 4}: the per-seed differences {1, 2, 3} have mean 2 = 4 - 2
  // and sample SD 1, so the paired SE is 1 / sqrt(3). As independent levels (SD 3 and 2):
  // sqrt(9/3 + 4/3) = sqrt(13/3), sqrt(13) times larger. Exact algebra: round-off tolerances.
  const auto fine = seededLevel(2, {1, 4, 7}), next = seededLevel(1, {0, 2, 4});
  auto p = discretisationPart({next, fine}, Finer::larger);
  EXPECT_NEAR(p.difference, 2.0, 1e-14);
  EXPECT_EQ(p.difference_se_rule, "paired");
  EXPECT_EQ(p.paired_seeds, 3);
  EXPECT_NEAR(p.difference_se, 1 / std::sqrt(3.0), 1e-14);
  EXPECT_NEAR(p.part_se, 1 / std::sqrt(3.0), 1e-14);
  EXPECT_TRUE(p.resolved) << "2 > 2 / sqrt(3) paired; 2 < 2 sqrt(13/3) as independent";
  const auto independent = mmval::validate::differenceError({2, fine.stats, {}}, {1, next.stats, {}});
  EXPECT_FALSE(independent.paired);
  EXPECT_NEAR(independent.se, std::sqrt(13.0 / 3.0), 1e-14);
  EXPECT_NEAR(independent.se / p.difference_se, std::sqrt(13.0), 1e-12);
  // Not the same seeds (seed 3 has no value at the finest level): independent, with the pairs that there were.
  p = discretisationPart({next, seededLevel(2, {1, 4, NAN})}, Finer::larger);
  EXPECT_EQ(p.difference_se_rule, "independent");
  EXPECT_EQ(p.paired_seeds, 2);
  EXPECT_NEAR(p.difference_se, std::sqrt(4.5 / 2 + 4.0 / 3), 1e-14);  // SD^2 of {1, 4} is 4.5
  // One seed: nothing to pair (and no spread): the current rule, 0.
  p = discretisationPart({seededLevel(1, {0}), seededLevel(2, {1})}, Finer::larger);
  EXPECT_EQ(p.difference_se_rule, "independent");
  EXPECT_EQ(p.difference_se, 0.0);
  // The resolution check of Richardson's second difference pairs too: f = 1 + 8 h^2 + noise(seed), noise
  // {0.3, -0.2, 0.1}: as independent levels the finest difference 0.375 is within 2 x 0.205 (SE^2 of the noise 0.0633 / 3, twice).
  const double noise[] = {0.3, -0.2, 0.1};
  const auto ladder = [&](double cpp) {
    std::vector<double> v;
    for (double n : noise) v.push_back(1 + 8 / (cpp * cpp) + n);
    return seededLevel(cpp, v);
  };
  p = discretisationPart({ladder(4), ladder(2), ladder(8)}, Finer::larger);
  EXPECT_EQ(p.method, "richardson") << p.note;
  EXPECT_NEAR(p.observed_order, 2.0, 1e-9);
  EXPECT_NEAR(p.part, 0.125, 1e-12);  // 8 / 8^2, the finest level's error
  auto unpaired = ladder(8);
  unpaired.by_seed.clear();
  p = discretisationPart({ladder(4), ladder(2), unpaired}, Finer::larger);
  EXPECT_EQ(p.method, "difference");
  EXPECT_THAT(p.note, HasSubstr("within 2 standard errors"));
}

// A test kind with a known ladder: f = 0.15 + 0.08 h^2 + 0.05 dt + noise(seed), h = 1 / cells_per_pixel,
// and g = 1 + 0.004 h^2 (no seed, no step dependence).
constexpr double kNoise[] = {0.013, -0.007, 0.021, -0.015, 0.004};
double ladderF(double cpp, double dt, int seed) { return 0.15 + 0.08 / (cpp * cpp) + 0.05 * dt + kNoise[seed - 1]; }

const mmval::CaseKindRegistry& ladderKind() {
  static const mmval::CaseKindRegistry registry = [] {
    mmval::CaseKindRegistry r;
    r.add({"test-ladder", "a metric with a known grid and step dependence",
           [](mmval::Schema& s) {
             s.real("numerics.cells_per_pixel", "grid").def(1.0);
             s.real("numerics.step", "step").def(0.1);
             s.integer("run.seed", "seed").def(1).min(1).max(5);
           },
           [](mmval::Schema& s) {
             s.metric("f", "1", "f0 + a h^2 + b dt + noise");
             s.metric("g", "1", "1 + 0.004 h^2");
           },
           [](const mmval::Case& c, const mmval::RunContext&) {
             mmval::RunOutput o;
             const double cpp = c.real("numerics.cells_per_pixel");
             o.metrics["f"] = ladderF(cpp, c.real("numerics.step"), static_cast<int>(c.integer("run.seed")));
             o.metrics["g"] = 1 + 0.004 / (cpp * cpp);
             return o;
           }});
    return r;
  }();
  return registry;
}

/// Names in the first column of the first `| name | unit | meaning |` table after the line `marker` of docs/outputs.md.
std::set<std::string> documentedNames(const std::string& marker) {
  std::ifstream in(fs::path(MMVAL_SOURCE_DIR) / "docs" / "outputs.md");
  std::string line;
  while (std::getline(in, line) && line != marker) {
  }
  while (std::getline(in, line) && line != "| name | unit | meaning |") {
  }
  std::set<std::string> names;
  while (std::getline(in, line) && line.starts_with("|")) {
    const std::string first = line.substr(2, line.find(" |", 2) - 2);
    if (first.size() > 2 && first.front() == '`') names.insert(first.substr(1, first.size() - 2));
  }
  return names;
}

std::set<std::string> keysOf(const nlohmann::json& j) {
  std::set<std::string> keys;
  for (const auto& [k, v] : j.items()) keys.insert(k);
  return keys;
}

TEST(Sweep, UncertaintyOfAKnownLadderAndItsReportPage) {
  const fs::path dir = mmval::test::freshTestFolder("sweep", "ladder");
  std::ofstream(dir / "ladder.toml") << "[case]\nname = \"ladder\"\nkind = \"test-ladder\"\n";
  mmval::validate::SweepOptions o;
  o.file = (dir / "ladder.toml").string();
  o.out = (dir / "sw").string();
  o.vary = {"numerics.cells_per_pixel=0.5,1,2", "numerics.step=0.4,0.2"};
  o.seeds = 5;
  o.metrics = {"f", "g"};  // the bare tolerance 0.1 is for these two; f has its own
  o.quiet = true;
  o.grid_key = "numerics.cells_per_pixel";
  o.step_key = "numerics.step";
  o.converged_within = {"0.1", "f=0.05"};
  mmval::validate::runSweep(o, ladderKind());
  const nlohmann::json sw = readJson(dir / "sw" / "sweep.json");
  EXPECT_FALSE(fs::exists(dir / "sw" / "result.json")) << "a sweep writes no result.json (docs/outputs.md says why)";
  ASSERT_EQ(sw.at("uncertainty").at("f").at("settings").size(), 1u);
  const auto& f = sw["uncertainty"]["f"]["settings"][0];
  // At the finest grid (2) and step (0.2): the five seeds' values, their statistics computed here.
  std::vector<double> finest;
  for (int seed = 1; seed <= 5; ++seed) finest.push_back(ladderF(2, 0.2, seed));
  const auto expected = sampleStats(finest);
  EXPECT_NEAR(f["value"].get<double>(), expected.mean, 1e-12);
  EXPECT_NEAR(f["seed_se"].get<double>(), expected.se, 1e-12);
  EXPECT_EQ(f["at"]["numerics.cells_per_pixel"], "2");
  EXPECT_EQ(f["at"]["numerics.step"], "0.2");
  // Grid: the noise is the same at every level (same seeds), so the ladder is exact: order 2, part a h1^2 = 0.02,
  // the limit 0.15 + b dt + mean noise.
  EXPECT_EQ(f["grid"]["method"], "richardson") << f["grid"]["note"];
  EXPECT_NEAR(f["grid"]["observed_order"].get<double>(), 2.0, 1e-9);
  EXPECT_NEAR(f["grid"]["part"].get<double>(), 0.02, 1e-12);
  EXPECT_NEAR(f["grid"]["extrapolated"].get<double>(), expected.mean - 0.02, 1e-12);
  EXPECT_NEAR(f["grid"]["difference"].get<double>(), -0.06, 1e-12);
  // Both levels ran seeds 1-5: paired, the seed's noise cancels in every per-seed difference (zero up to round-off),
  // where independent levels would give sqrt(2) x the seed SE.
  EXPECT_EQ(f["grid"]["difference_se_rule"], "paired");
  EXPECT_EQ(f["grid"]["paired_seeds"], 5);
  EXPECT_NEAR(f["grid"]["difference_se"].get<double>(), 0.0, 1e-12);
  // Step: two levels, b (0.2 - 0.4) = -0.01.
  EXPECT_EQ(f["step"]["method"], "difference");
  EXPECT_NEAR(f["step"]["difference"].get<double>(), -0.01, 1e-12);
  EXPECT_NEAR(f["combined"].get<double>(), std::sqrt(expected.se * expected.se + 0.02 * 0.02 + 0.01 * 0.01), 1e-12);
  // f's own tolerance 0.05: the finest grid difference 0.06 is beyond it. g (0.1 for every metric): converged.
  EXPECT_EQ(f["converged"], false) << f["verdict"];
  const auto& g = sw["uncertainty"]["g"]["settings"][0];
  EXPECT_EQ(g["converged"], true) << g["verdict"];
  EXPECT_NEAR(g["grid"]["observed_order"].get<double>(), 2.0, 1e-9);
  EXPECT_NEAR(g["grid"]["part"].get<double>(), 0.001, 1e-12);
  EXPECT_TRUE(g["seed_se"].is_number() && g["seed_se"].get<double>() == 0.0) << "no seed dependence: zero spread";

  // docs/outputs.md lists exactly what sweep.json holds.
  EXPECT_EQ(documentedNames("### Sweep: `sweep.json`"), keysOf(sw));
  EXPECT_EQ(documentedNames("### Sweep: an entry of `uncertainty.<metric>.settings`"), keysOf(f));
  EXPECT_EQ(documentedNames("A part (`grid`, `step`):"), keysOf(f["grid"]));

  // The report of the sweep folder: one sweep (its 30 runs not listed one by one), its page with the table and figure.
  const auto input = mmval::reports::collect({dir / "sw"});
  ASSERT_EQ(input.sweeps.size(), 1u);
  EXPECT_TRUE(input.summary.results.empty());
  mmval::reports::writeReport(input, dir / "report");
  std::stringstream page, index, md;
  page << std::ifstream(dir / "report" / "cases" / "sweep-sw.html").rdbuf();
  index << std::ifstream(dir / "report" / "index.html").rdbuf();
  md << std::ifstream(dir / "report" / "report.md").rdbuf();
  EXPECT_THAT(index.str(), HasSubstr("cases/sweep-sw.html"));
  EXPECT_THAT(index.str(), HasSubstr("1 of 2"));  // f not converged, g converged
  EXPECT_THAT(page.str(), HasSubstr(fmt::format("{:.5g}", expected.mean)));
  EXPECT_THAT(page.str(), HasSubstr("0.02 (richardson, order 2)"));
  EXPECT_THAT(page.str(), HasSubstr("NOT converged within 0.05"));
  EXPECT_THAT(md.str(), HasSubstr("Uncertainty of ladder (sweep sw)"));
  if (mmval::reports::gnuplotAvailable()) {
    EXPECT_THAT(page.str(), HasSubstr("<svg"));
    EXPECT_TRUE(fs::exists(dir / "report" / "figures" / "sweep-sw-f.csv"));
  }
  EXPECT_TRUE(mmval::reports::brokenLinks(dir / "report").empty());
}

TEST(Sweep, DiscretisationAxesMustBeVariedNumbersBeforeAnyRun) {
  const fs::path dir = mmval::test::freshTestFolder("sweep", "ladder-bad");
  std::ofstream(dir / "ladder.toml") << "[case]\nname = \"ladder\"\nkind = \"test-ladder\"\n";
  mmval::validate::SweepOptions o;
  o.file = (dir / "ladder.toml").string();
  o.out = (dir / "sw").string();
  o.vary = {"numerics.cells_per_pixel=0.5,1,2"};
  o.quiet = true;
  const auto refused = [&](const char* option) {
    try {
      mmval::validate::runSweep(o, ladderKind());
      ADD_FAILURE() << option << ": accepted";
    } catch (const mmval::InputError& e) {
      EXPECT_THAT(std::string(e.what()), HasSubstr(option));
    }
    EXPECT_FALSE(fs::exists(dir / "sw" / "runs")) << option;
  };
  o.grid_key = "numerics.step";  // not varied
  refused("--grid");
  o.grid_key = "numerics.cells_per_pixel";
  o.vary = {"numerics.cells_per_pixel=0.5,1,\"two\""};
  refused("--grid");
  o.vary = {"numerics.cells_per_pixel=0.5,1,2"};
  o.step_key = "numerics.cells_per_pixel";
  refused("--step");
  o.step_key.clear();
  o.converged_within = {"-1"};
  refused("--converged-within");
}


// ---- --jobs: the runs as child processes ------------------------------------

/// A sweep's sweep.csv and sweep.json without what is timing (wall_s, engine_wall_time,
/// particle_steps_per_second): what two sweeps of the same runs must give alike.
const std::set<std::string> kTimings = {"wall_s", "engine_wall_time", "particle_steps_per_second"};
nlohmann::json withoutTimings(nlohmann::json j) {
  if (j.is_object()) {
    for (const auto& t : kTimings) j.erase(t);
    for (auto& [k, v] : j.items()) v = withoutTimings(v);
  } else if (j.is_array()) {
    for (auto& v : j) v = withoutTimings(v);
  }
  return j;
}
std::vector<std::vector<std::string>> csvWithoutTimings(const fs::path& file) {
  std::ifstream in(file);
  std::string line;
  std::vector<std::vector<std::string>> rows;
  std::vector<bool> keep;
  while (std::getline(in, line)) {
    std::vector<std::string> cells, kept;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) cells.push_back(cell);  // no quoted commas in these sweeps
    if (keep.empty())
      for (const auto& c : cells) keep.push_back(kTimings.count(c) == 0);
    for (std::size_t i = 0; i < cells.size(); ++i)
      if (i >= keep.size() || keep[i]) kept.push_back(cells[i]);
    rows.push_back(kept);
  }
  return rows;
}

TEST(Sweep, JobsRunTheRunsAsChildProcessesWithTheTablesOfOneProcess) {
  // Three channel runs (quoted values in --set and --vary), one after another and two at a time (child processes
  // running `mmval run --set ...`: their result.json carries the case hash the sweep checks, so every override
  // reached the child as given).
  const fs::path dir = mmval::test::freshTestFolder("sweep", "jobs");
  const std::string args = "sweep " + kChannel + kSmall + " --vary 'channel.mean_velocity=\"0.36 mm/s\",\"0.72 mm/s\",\"1.08 mm/s\"' --out ";
  const auto one = mmval::test::runMmval(args + (dir / "one").string());
  ASSERT_EQ(one.status, 0) << one.output;
  const auto two = mmval::test::runMmval(args + (dir / "two").string() + " --jobs 2");
  ASSERT_EQ(two.status, 0) << two.output;
  EXPECT_THAT(two.output, HasSubstr("sweep [3/3 done]"));
  EXPECT_EQ(csvWithoutTimings(dir / "two" / "sweep.csv"), csvWithoutTimings(dir / "one" / "sweep.csv"));
  EXPECT_EQ(csvWithoutTimings(dir / "two" / "sweep.csv").size(), 4u);
  EXPECT_EQ(withoutTimings(readJson(dir / "two" / "sweep.json")), withoutTimings(readJson(dir / "one" / "sweep.json")));
  EXPECT_FALSE(fs::exists(dir / "two" / "runs" / "run-001.log")) << "a run's log goes once the run is recorded";
  // --resume with --jobs keeps the complete runs without starting a process.
  const auto again = mmval::test::runMmval(args + (dir / "two").string() + " --jobs 2 --resume");
  ASSERT_EQ(again.status, 0) << again.output;
  EXPECT_THAT(again.output, HasSubstr("kept the complete earlier run"));
  EXPECT_THAT(again.output, Not(HasSubstr("done]")));
  EXPECT_EQ(withoutTimings(readJson(dir / "two" / "sweep.json")), withoutTimings(readJson(dir / "one" / "sweep.json")));
}

TEST(Sweep, ANumericalFailureInAChildIsRecordedAsInOneProcess) {
  // A square array at 8 cells per side: solid fraction 0.3 solves (PETSc in the child, no mpirun), 0.7 leaves a
  // throat of 0.5 cells, a numerical failure (exit 5) that the sweep records in its row, in the same words.
  const fs::path dir = mmval::test::freshTestFolder("sweep", "jobs-failure");
  const std::string args = "sweep " + std::string(MMVAL_SOURCE_DIR) + "/cases/fluid-square-array-phi050.toml --set 'numerics.levels=[8]'" +
                           " --vary geometry.solid_fraction=0.3,0.7 --quiet --out ";
  const auto one = mmval::test::runMmval(args + (dir / "one").string());
  ASSERT_EQ(one.status, 0) << one.output;
  const auto two = mmval::test::runMmval(args + (dir / "two").string() + " --jobs 2");
  ASSERT_EQ(two.status, 0) << two.output;
  const auto rows = csvWithoutTimings(dir / "two" / "sweep.csv");
  EXPECT_EQ(rows, csvWithoutTimings(dir / "one" / "sweep.csv"));
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[1][1], "metrics failed");  // F* at 8 cells is outside the case's 2 %: a result all the same
  EXPECT_THAT(rows[2][1], HasSubstr("numerical failure: the narrowest throat of the flow path is 0.50 cells wide"));
  const nlohmann::json sw = readJson(dir / "two" / "sweep.json");
  EXPECT_EQ(sw.at("failed_runs"), 1);
  EXPECT_EQ(withoutTimings(sw), withoutTimings(readJson(dir / "one" / "sweep.json")));
}

TEST(Sweep, AChildThatFailsEndsTheSweepOnceTheOthersHaveFinished) {
  // A stand-in for `mmval run` (SweepOptions::executable): run-002 fails at once as a bug would (exit 4); the
  // others record their arguments, take a second and end in a numerical failure. With two at a time, run-001
  // is still running when run-002 fails: the sweep waits for it, starts no other, and names run-002.
  const fs::path dir = mmval::test::freshTestFolder("sweep", "jobs-fatal");
  std::ofstream(dir / "ladder.toml") << "[case]\nname = \"ladder\"\nkind = \"test-ladder\"\n";
  const fs::path fake = dir / "fake-mmval";
  std::ofstream(fake) << "#!/bin/sh\n"
                         "printf '%s\\n' \"$@\" > \"$4.args\"\n"
                         "printf '%s' \"$MMVAL_AUTO_THREADS\" > \"$4.threads\"\n"
                         "case \"$4\" in *run-002) echo 'mmval: internal error: boom' >&2; exit 4;; esac\n"
                         "sleep 1; touch \"$4.finished\"; echo 'mmval: numerical failure: fake' >&2; exit 5\n";
  fs::permissions(fake, fs::perms::owner_all);
  mmval::validate::SweepOptions o;
  o.file = (dir / "ladder.toml").string();
  o.out = (dir / "sw").string();
  o.set = {"numerics.step=0.25"};
  o.seeds = 3;
  o.quiet = true;
  o.jobs = 2;
  o.executable = fake.string();
  const fs::path runs = dir / "sw" / "runs";
  try {
    mmval::validate::runSweep(o, ladderKind());
    ADD_FAILURE() << "a child's exit status 4 did not end the sweep";
  } catch (const std::runtime_error& e) {
    const std::string m = e.what();
    EXPECT_THAT(m, HasSubstr("run-002"));
    EXPECT_THAT(m, HasSubstr("exit status 4 (a bug in mmval): internal error: boom"));
    EXPECT_THAT(m, HasSubstr((runs / "run-002.log").string()));
  }
  EXPECT_TRUE(fs::exists(runs / "run-001.finished")) << "the sweep did not wait for run-001";
  EXPECT_FALSE(fs::exists(runs / "run-003.args")) << "a run was started after the failure";
  EXPECT_TRUE(fs::exists(runs / "run-002.log")) << "the failed run's log is kept";
  // The child's command line: the case, its folder, quiet, every override of the run in order.
  std::ifstream in(runs / "run-001.args");
  std::vector<std::string> argv;
  for (std::string a; std::getline(in, a);) argv.push_back(a);
  EXPECT_EQ(argv, (std::vector<std::string>{"run", o.file, "--out", (runs / "run-001").string(), "--quiet", "--set", "numerics.step=0.25", "--set",
                                            "run.seed=1"}));
  // Each child's share of the cores for an "auto" thread count (two at a time: half of them, at least 1),
  // and the sweep's own environment as it was.
  std::ifstream threads(runs / "run-001.threads");
  std::string share;
  std::getline(threads, share);
  EXPECT_EQ(share, std::to_string(std::max(1u, std::max(1u, std::thread::hardware_concurrency()) / 2)));
  EXPECT_EQ(std::getenv(mmval::kAutoThreadsVariable), nullptr);
}

}  // namespace
