// result.json files written by real runs of cheap kinds pass the report's
// shape check, and their declared details fields read back through the
// accessors with the values the runs must have: the plane Poiseuille ladder
// (channel, PETSc on 1 rank) against the exact flow rate, and compare-tracks
// on tracks whose step count is known by construction. A declared field spoiled
// in a real file is named with the file.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "../TestScratch.hpp"
#include "mmval/compare/Kinds.hpp"
#include "mmval/core/DetailFields.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/core/Tracks.hpp"
#include "mmval/reports/InputFiles.hpp"
#include "mmval/reports/JsonShape.hpp"
#include "mmval/simulate/Kinds.hpp"

namespace mmval::reports {
namespace {

namespace fs = std::filesystem;
using F = DetailField;

const CaseKindRegistry& registry() {
  static const CaseKindRegistry r = [] {
    CaseKindRegistry reg;
    simulate::registerFluidKinds(reg);
    compare::registerCompareKinds(reg);
    return reg;
  }();
  return r;
}

/// Runs `c` as `mmval run` does and reads its result.json back from disk.
nlohmann::json runAndRead(const Case& c, const std::string& folder) {
  RunOptions o;
  o.quiet = true;
  const RunSummary s = runCase(c, registry(), test::scratch(folder), o);
  return readJsonFile(s.result_file);
}

TEST(DetailFieldsRun, PoiseuilleLadderReadsBackThroughTheDeclaredFields) {
  const Case c = Case::load(fs::path(MMVAL_SOURCE_DIR) / "cases" / "fluid-poiseuille.toml", registry());
  const nlohmann::json r = runAndRead(c, "details-poiseuille");
  EXPECT_NO_THROW(checkResultShape(r, "result.json")) << r["details"].dump(1);
  const nlohmann::json& d = resultDetails(r);
  EXPECT_THAT(detailString(d, F::solver).value_or(""), ::testing::StartsWith("mmval"));
  // Exact flow rate per unit depth between plates W apart: q = G W^3 / (12 mu) (the case file's numbers).
  const double q_exact = 1e4 * std::pow(100e-6, 3) / (12 * 1e-3);
  const auto rows = detailRows(d, F::ladder);
  ASSERT_EQ(rows.size(), 3U) << "numerics.levels = [8, 16, 32]";
  long long cells_before = 0;
  for (const DetailRow& row : rows) {
    SCOPED_TRACE(row.path);
    const auto value = detailNumber(row, F::ladder_value), error = detailNumber(row, F::ladder_error);
    ASSERT_TRUE(value && error);
    // error is the relative error against the acceptance reference 8.33333333e-7 m2/s (round-off class).
    EXPECT_NEAR(*error, *value / 8.33333333e-7 - 1, 1e-12);
    EXPECT_GE(detailNumber(row, F::ladder_wall_seconds).value_or(-1), 0.0);
    const long long cells = detailInteger(row, F::ladder_cells).value_or(0);
    EXPECT_GT(cells, cells_before) << "levels refine";
    cells_before = cells;
  }
  // The finest level within the case's 0.5 % of the exact solution (second order at 32 cells).
  EXPECT_NEAR(*detailNumber(rows.back(), F::ladder_value), q_exact, 5e-3 * q_exact);
  EXPECT_EQ(detailInteger(d, F::cells), cells_before) << "details.cells is the finest level's";
}

/// Ten particles 8 um apart in y drifting along x at `speed` (m/s) over 40 frames of 0.1 s.
Tracks drift(double speed) {
  Tracks t;
  for (int p = 0; p < 10; ++p)
    for (int f = 0; f < 40; ++f) {
      TrackPoint q;
      q.frame = f;
      q.particle = p;
      q.t = 0.1 * f;
      q.x = 10e-6 + f * speed * 0.1;
      q.y = 5e-6 + p * 8e-6;
      t.points.push_back(q);
    }
  return t;
}

TEST(DetailFieldsRun, CompareTracksCountsReadBackAndASpoiledFieldIsNamed) {
  const fs::path exp = test::scratch("details-exp.csv"), sim = test::scratch("details-sim.csv");
  writeTracksCsv(exp, drift(20e-6), 1e-6);
  writeTracksCsv(sim, drift(21e-6), 1e-6);
  const std::string text = "[case]\nname = \"details-compare\"\nkind = \"compare-tracks\"\n[inputs]\nexperiment = \"" + exp.string() +
                           "\"\nsimulation = \"" + sim.string() + "\"\npixel_size = \"1 um\"\n";
  const nlohmann::json r = runAndRead(Case::parse(text, test::scratch("details-compare.toml"), registry()), "details-compare");
  EXPECT_NO_THROW(checkResultShape(r, "result.json")) << r["details"].dump(1);
  const auto side = detailObject(resultDetails(r), F::experiment);
  ASSERT_TRUE(side.has_value()) << r["details"].dump(1);
  // Every track moves 2 um a frame, 78 um in all (far above the 2 um immobile distance), and never rests:
  // 10 mobile tracks of 40 points, 39 steps each.
  EXPECT_EQ(detailInteger(*side, F::experiment_mobile), 10);
  EXPECT_EQ(detailInteger(*side, F::experiment_steps), 10 * 39);

  nlohmann::json spoiled = r;
  spoiled["details"]["experiment"]["steps"] = "390";
  try {
    checkResultShape(spoiled, "runs/details-compare/result.json");
    ADD_FAILURE() << "a string in details.experiment.steps passed";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("runs/details-compare/result.json: key 'details.experiment.steps': wrong type; got \"390\" (string); "
                                               "expected an integer"));
  }
}

}  // namespace
}  // namespace mmval::reports
