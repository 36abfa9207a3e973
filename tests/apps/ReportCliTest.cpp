// `mmval report` and `report --diff` on files that are not what mmval wrote:
// each exits 2 naming the file and the field, not a bare JSON type error (exit 4).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "RunMmval.hpp"

#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

using mmval::test::Outcome;

Outcome mmval(const std::string& args) { return mmval::test::runMmval(args); }

fs::path scratch(const std::string& name) { return mmval::test::freshTestFolder("cli-report", name); }

nlohmann::json metricsDocument(double value) {
  return {{"schema", "mmval-metrics/1"},
          {"metrics", {{{"case", "self"}, {"name", "mean_speed"}, {"value", value}, {"unit", "um/s"}, {"tolerance", "20 %"}, {"pass", true}}}}};
}

/// `report --diff A B` with B the text given and A a valid metrics.json.
Outcome diffAgainst(const fs::path& d, const std::string& after_text) {
  std::ofstream(d / "before.json") << metricsDocument(30.0).dump();
  std::ofstream(d / "after.json") << after_text;
  return mmval("report --diff " + (d / "before.json").string() + " " + (d / "after.json").string());
}

TEST(ReportCli, WrongShapeResultExitsTwoNamingFileAndField) {
  const fs::path d = scratch("wrong-shape");
  fs::create_directories(d / "run");
  // A result.json whose metric says "pass": "yes" instead of true.
  std::ofstream(d / "run" / "result.json") << R"({"schema": "mmval-result/1", "case": {"name": "x", "kind": "channel", "hash": "0"},
    "metrics": [{"name": "q", "value": 1.0, "unit": "1", "reference": 1.0, "error": 0.0, "tolerance": "1 %", "pass": "yes"}],
    "all_pass": true, "cost": {"wall_seconds": 1, "peak_memory_bytes": 1}, "details": null,
    "provenance": {"mmval_version": "t", "git_hash": "t", "compiler": "t", "build_type": "t", "host": "t"}})";
  const Outcome o = mmval("report " + (d / "run").string() + " --out " + (d / "report").string());
  EXPECT_EQ(o.status, 2) << o.output;
  EXPECT_THAT(o.output, HasSubstr((d / "run" / "result.json").string() + ": key 'metrics[0].pass': wrong type; got \"yes\" (string); expected true or false or null"));
}

TEST(ReportCli, ResultOfTheWrongTypeExitsTwo) {
  const fs::path d = scratch("array");
  fs::create_directories(d / "run");
  std::ofstream(d / "run" / "result.json") << "[1, 2, 3]";
  const Outcome o = mmval("report " + (d / "run").string() + " --out " + (d / "report").string());
  EXPECT_EQ(o.status, 2) << o.output;
  EXPECT_THAT(o.output, HasSubstr("result.json: wrong type; got [1,2,3] (array); expected an object"));
}

TEST(ReportCli, DiffOfWrongTypesExitsTwoNamingFileAndField) {
  const fs::path d = scratch("diff-types");
  nlohmann::json after = metricsDocument(31.0);
  after["metrics"][0]["value"] = "31 um/s";
  const Outcome o = diffAgainst(d, after.dump());
  EXPECT_EQ(o.status, 2) << o.output;
  EXPECT_THAT(o.output, HasSubstr((d / "after.json").string() + ": key 'metrics[0].value': wrong type; got \"31 um/s\" (string)"));
}

TEST(ReportCli, DiffOfAWrongShapeExitsTwo) {
  const fs::path d = scratch("diff-shape");
  const Outcome o = diffAgainst(d, R"({"metrics": {"mean_speed": 31}})");
  EXPECT_EQ(o.status, 2) << o.output;
  EXPECT_THAT(o.output, HasSubstr("after.json: key 'metrics': wrong type; got {\"mean_speed\":31} (object); expected a list"));
}

TEST(ReportCli, DiffOfNonJsonEmptyAndMissingFilesExitsTwo) {
  const fs::path d = scratch("diff-files");
  const Outcome text = diffAgainst(d, "mean_speed,31\n");
  EXPECT_EQ(text.status, 2) << text.output;
  EXPECT_THAT(text.output, HasSubstr("after.json:1: not valid JSON"));
  const Outcome empty = diffAgainst(d, "");
  EXPECT_EQ(empty.status, 2) << empty.output;
  EXPECT_THAT(empty.output, HasSubstr("after.json: empty file"));
  const Outcome missing = mmval("report --diff " + (d / "before.json").string() + " " + (d / "nothing.json").string());
  EXPECT_EQ(missing.status, 2) << missing.output;
  EXPECT_THAT(missing.output, HasSubstr((d / "nothing.json").string() + ": no such file"));
}

TEST(ReportCli, DiffOfAHugeFileExitsTwoWithoutReadingIt) {
  const fs::path d = scratch("diff-huge");
  std::ofstream(d / "after.json") << "{";
  fs::resize_file(d / "after.json", std::uintmax_t{300} << 20);  // sparse: no disk used
  std::ofstream(d / "before.json") << metricsDocument(30.0).dump();
  const Outcome o = mmval("report --diff " + (d / "before.json").string() + " " + (d / "after.json").string());
  EXPECT_EQ(o.status, 2) << o.output;
  EXPECT_THAT(o.output, HasSubstr("after.json: file too large to be one mmval wrote; got 300.0 MiB; expected at most 256.0 MiB"));
  fs::remove(d / "after.json");
}

TEST(ReportCli, DiffOfValidFilesListsTheChange) {
  const fs::path d = scratch("diff-ok");
  const Outcome o = diffAgainst(d, metricsDocument(40.0).dump());
  EXPECT_EQ(o.status, 0) << o.output;
  EXPECT_THAT(o.output, HasSubstr("| self/mean_speed | 30 | 40 | +33.3 % | 20 % | pass | pass |"));
}

}  // namespace
