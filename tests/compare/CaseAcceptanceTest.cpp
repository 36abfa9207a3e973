// A compare-tracks case's own [[acceptance]] on a metric the comparison only reports
// (speed_wasserstein1): the run judges it against the entry, once, with its value.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "mmval/compare/Kinds.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/core/Tracks.hpp"
#include "TrackPoints.hpp"

#include "../TestScratch.hpp"

namespace mmval::compare {
namespace {

using test_support::pt;

/// Five particles 10 um apart in y, each moving along x at `speed` um/s for 20 frames of 0.1 s.
Tracks straight(double speed) {
  Tracks t;
  for (int p = 0; p < 5; ++p)
    for (int f = 0; f < 20; ++f) t.points.push_back(pt(f, p, 0.1 * f, 1e-6 * (10 + speed * 0.1 * f), 1e-6 * (5 + 10 * p)));
  return t;
}

/// Every step of the experiment is 30 um/s and every step of the simulation 45 um/s, so the
/// Wasserstein-1 distance of the two speed distributions is 45 - 30 = 15 um/s exactly.
RunSummary runWithW1Tolerance(const std::string& tolerance, const std::string& dir_name) {
  const auto dir = mmval::test::scratch(dir_name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  writeTracksCsv(dir / "exp.csv", straight(30));
  writeTracksCsv(dir / "sim.csv", straight(45));
  CaseKindRegistry registry;
  registerCompareKinds(registry);
  const std::string text = "[case]\nname = \"w1\"\nkind = \"compare-tracks\"\n[inputs]\nexperiment = \"exp.csv\"\nsimulation = \"sim.csv\"\n"
                           "[[acceptance]]\nmetric = \"speed_wasserstein1\"\nreference = \"0 um/s\"\ntolerance = \"" + tolerance +
                           "\"\nreason = \"test\"\n";
  const Case c = Case::parse(text, dir / "case.toml", registry);
  return runCase(c, registry, dir / "out", {.quiet = true, .resume = false});
}

void expectOneJudgedW1(const RunSummary& s, bool pass) {
  int rows = 0;
  for (const auto& m : s.metrics) {
    if (m.name != "speed_wasserstein1") continue;
    ++rows;
    EXPECT_NEAR(m.value, 15.0, 1e-9);
    EXPECT_EQ(m.unit, "um/s");
    ASSERT_TRUE(m.pass.has_value());
    EXPECT_EQ(*m.pass, pass);
  }
  EXPECT_EQ(rows, 1);
  if (!pass) EXPECT_FALSE(s.all_pass);  // a failed case entry fails the run
}

TEST(CompareCaseAcceptance, InfoMetricJudgedByTheCaseEntry) {
  expectOneJudgedW1(runWithW1Tolerance("20 um/s", "compare-w1-pass"), true);
  expectOneJudgedW1(runWithW1Tolerance("10 um/s", "compare-w1-fail"), false);
}

}  // namespace
}  // namespace mmval::compare
