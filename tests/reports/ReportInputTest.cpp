// The files a report reads may be anything a user points at: missing, empty,
// not JSON, of the wrong shape or far too large. Each is an InputError naming
// the file and the field, never a bare JSON type error.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <ostream>

#include <nlohmann/json.hpp>

#include "../InputErrorMessage.hpp"
#include "../TestScratch.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/reports/InputFiles.hpp"
#include "mmval/reports/JsonShape.hpp"
#include "mmval/reports/Report.hpp"

namespace mmval::reports {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

fs::path writeFile(const std::string& name, const std::string& text) {
  const fs::path file = test::scratch(name);
  fs::create_directories(file.parent_path());
  std::ofstream(file) << text;
  return file;
}

/// The message of the InputError `f` throws ("(no InputError)" when it throws none).
std::string inputErrorOf(const std::function<void()>& f) { return mmval::test::inputErrorMessage(f); }

nlohmann::json metric(const std::string& name, double value, const std::string& tolerance, bool pass) {
  return {{"name", name}, {"metric", name}, {"label", ""}, {"dimension", "m s^-1"}, {"value", value}, {"unit", "um/s"}, {"reference", 10.0},
          {"error", value / 10.0 - 1}, {"error_kind", "relative"}, {"tolerance", tolerance}, {"pass", pass}, {"source", "experiment tracks"},
          {"source_ref", {{"citation", "experiment tracks"}, {"locator", ""}, {"doi", ""}}}, {"reference_setup", ""}};
}

/// What `mmval run` writes, reduced to what the report reads.
nlohmann::json validResult() {
  return {{"schema", "mmval-result/1"},
          {"case", {{"name", "self"}, {"kind", "compare-tracks"}, {"hash", "0123456789abcdef"}, {"file", "case.toml"}}},
          {"metrics", nlohmann::json::array({metric("mean_speed", 11.0, "20 %", true)})},
          {"all_pass", true},
          {"cost", {{"wall_seconds", 1.5}, {"peak_memory_bytes", 1048576.0}}},
          {"details", {{"Re", 20.0}, {"statistics_window_s", {6.5, 7.8}}}},
          {"files", {"metrics.json"}},
          {"provenance", {{"mmval_version", "test"}, {"git_hash", "test"}, {"compiler", "test"}, {"build_type", "test"}, {"host", "test"}}}};
}

TEST(InputFiles, MissingEmptyFolderAndTooLargeNameTheFile) {
  EXPECT_THAT(inputErrorOf([] { readJsonFile("/nonexistent/metrics.json"); }), HasSubstr("/nonexistent/metrics.json: no such file"));
  const fs::path empty = writeFile("empty.json", "  \n");
  EXPECT_THAT(inputErrorOf([&] { readJsonFile(empty); }), HasSubstr("empty.json: empty file"));
  EXPECT_THAT(inputErrorOf([] { readJsonFile(test::scratch("")); }), HasSubstr("is a folder, not a file"));
  const fs::path big = writeFile("big.json", std::string(2048, ' ') + "{}");
  const std::string m = inputErrorOf([&] { readJsonFile(big, 1024); });
  EXPECT_THAT(m, HasSubstr("big.json: file too large"));
  EXPECT_THAT(m, HasSubstr("got 2050 bytes; expected at most 1024 bytes"));
  EXPECT_EQ(readJsonFile(big, 4096), nlohmann::json::object());
}

TEST(InputFiles, SyntaxErrorNamesTheLine) {
  const fs::path bad = writeFile("bad.json", "{\n  \"metrics\": [\n    1,\n  oops\n]}\n");
  const std::string m = inputErrorOf([&] { readJsonFile(bad); });
  EXPECT_THAT(m, HasSubstr("bad.json:4: not valid JSON"));
}

// Found by fuzz_result_json (fuzz/findings/result_json-number-overflow.json):
// a number beyond double made the JSON parser throw out_of_range, which escaped as exit 4.
TEST(InputFiles, NumberBeyondDoubleIsAnInputError) {
  const fs::path big = writeFile("big.json", "{\"metrics\": [1e400]}\n");
  EXPECT_THAT(inputErrorOf([&] { readJsonFile(big); }), HasSubstr("big.json: not usable JSON"));
}

TEST(JsonShape, ValidResultPasses) { EXPECT_NO_THROW(checkResultShape(validResult(), "result.json")); }

TEST(JsonShape, ResultWrittenBeforeTheTypedFieldsStillPasses) {
  nlohmann::json r = validResult();
  for (const char* key : {"metric", "label", "dimension", "source_ref", "reference_setup"}) r["metrics"][0].erase(key);
  EXPECT_NO_THROW(checkResultShape(r, "result.json"));
}

/// One field of a valid result.json spoiled, and the field path the error must name.
struct Spoiled {
  std::string name;
  std::function<void(nlohmann::json&)> spoil;
  std::string field;
};

void PrintTo(const Spoiled& s, std::ostream* os) { *os << s.name << " (" << s.field << ")"; }

class ResultShape : public ::testing::TestWithParam<Spoiled> {};

TEST_P(ResultShape, NamesFileAndField) {
  nlohmann::json r = validResult();
  GetParam().spoil(r);
  const std::string m = inputErrorOf([&] { checkResultShape(r, "runs/x/result.json"); });
  EXPECT_THAT(m, HasSubstr("runs/x/result.json: key '" + GetParam().field + "'"));
}

INSTANTIATE_TEST_SUITE_P(
    Fields, ResultShape,
    ::testing::Values(Spoiled{"CaseNameNumber", [](nlohmann::json& r) { r["case"]["name"] = 3; }, "case.name"},
                      Spoiled{"CaseMissing", [](nlohmann::json& r) { r.erase("case"); }, "case"},
                      Spoiled{"MetricsObject", [](nlohmann::json& r) { r["metrics"] = nlohmann::json::object(); }, "metrics"},
                      Spoiled{"PassString", [](nlohmann::json& r) { r["metrics"][0]["pass"] = "yes"; }, "metrics[0].pass"},
                      Spoiled{"ValueString", [](nlohmann::json& r) { r["metrics"][0]["value"] = "11"; }, "metrics[0].value"},
                      Spoiled{"ReferenceOneEnd", [](nlohmann::json& r) { r["metrics"][0]["reference"] = {1.0}; }, "metrics[0].reference"},
                      Spoiled{"MetricNumber", [](nlohmann::json& r) { r["metrics"][0]["metric"] = 1; }, "metrics[0].metric"},
                      Spoiled{"LabelNull", [](nlohmann::json& r) { r["metrics"][0]["label"] = nullptr; }, "metrics[0].label"},
                      Spoiled{"SetupList", [](nlohmann::json& r) { r["metrics"][0]["reference_setup"] = {"unbounded"}; }, "metrics[0].reference_setup"},
                      Spoiled{"SourceRefString", [](nlohmann::json& r) { r["metrics"][0]["source_ref"] = "Dennis"; }, "metrics[0].source_ref"},
                      Spoiled{"SourceRefNoDoi", [](nlohmann::json& r) { r["metrics"][0]["source_ref"].erase("doi"); }, "metrics[0].source_ref.doi"},
                      Spoiled{"AllPassString", [](nlohmann::json& r) { r["all_pass"] = "true"; }, "all_pass"},
                      Spoiled{"WallSecondsMissing", [](nlohmann::json& r) { r["cost"].erase("wall_seconds"); }, "cost.wall_seconds"},
                      Spoiled{"HostNumber", [](nlohmann::json& r) { r["provenance"]["host"] = 1; }, "provenance.host"},
                      Spoiled{"ReString", [](nlohmann::json& r) { r["details"]["Re"] = "twenty"; }, "details.Re"},
                      Spoiled{"WindowOneEnd", [](nlohmann::json& r) { r["details"]["statistics_window_s"] = {6.5}; }, "details.statistics_window_s"},
                      Spoiled{"SolverNumber", [](nlohmann::json& r) { r["details"]["solver"] = 2; }, "details.solver"},
                      Spoiled{"PeriodsFraction", [](nlohmann::json& r) { r["details"]["shedding_periods"] = 2.5; }, "details.shedding_periods"},
                      Spoiled{"LadderWallString",
                              [](nlohmann::json& r) { r["details"]["ladder"] = {{{"wall_seconds", 1.0}}, {{"wall_seconds", "1 s"}}}; },
                              "details.ladder[1].wall_seconds"},
                      Spoiled{"EngineParticlesString",
                              [](nlohmann::json& r) { r["details"]["engine_comparison"] = {{{"particles", "forty"}}}; },
                              "details.engine_comparison[0].particles"},
                      Spoiled{"ExperimentList", [](nlohmann::json& r) { r["details"]["experiment"] = {1, 2}; }, "details.experiment"},
                      Spoiled{"DetailsMissing", [](nlohmann::json& r) { r.erase("details"); }, "details"},
                      Spoiled{"OtherSchema", [](nlohmann::json& r) { r["schema"] = "mmval-compare/1"; }, "schema"}),
    [](const ::testing::TestParamInfo<Spoiled>& info) { return info.param.name; });

TEST(JsonShape, UndeclaredDetailsAreAllowedAndListed) {
  nlohmann::json r = validResult();
  r["details"]["engine_settings"] = {{"step", 0.1}};
  r["details"]["note"] = "informational";
  EXPECT_EQ(checkResultShape(r, "result.json"), (std::vector<std::string>{"engine_settings", "note"}));
  r["details"] = nullptr;  // a run with no details at all
  EXPECT_TRUE(checkResultShape(r, "result.json").empty());
}

TEST(JsonShape, WholeDocumentOfTheWrongTypeIsNamed) {
  const std::string m = inputErrorOf([] { checkResultShape(nlohmann::json::array({1, 2}), "result.json"); });
  EXPECT_THAT(m, HasSubstr("result.json: wrong type; got [1,2] (array); expected an object"));
}

TEST(Collect, WrongShapeResultNamesFileAndField) {
  nlohmann::json r = validResult();
  r["cost"]["wall_seconds"] = "1.5 s";
  const fs::path dir = test::scratch("wrong-shape");
  writeFile("wrong-shape/result.json", r.dump());
  const std::string m = inputErrorOf([&] { collect({dir}); });
  EXPECT_THAT(m, HasSubstr((dir / "result.json").string() + ": key 'cost.wall_seconds': wrong type; got \"1.5 s\" (string); expected a number"));
}

TEST(Collect, CompareMetricsWithoutRegionSidesNamesTheField) {
  const nlohmann::json c{{"schema", "mmval-compare/1"}, {"metrics", nlohmann::json::array()}, {"all_pass", true}, {"regions", {{"rule", "x"}}}};
  const fs::path dir = test::scratch("compare-shape");
  writeFile("compare-shape/metrics.json", c.dump());
  EXPECT_THAT(inputErrorOf([&] { collect({dir}); }), HasSubstr("metrics.json: key 'regions.experiment': missing field"));
}

TEST(Diff, WrongTypesNameFileAndField) {
  const fs::path good = writeFile("good-metrics.json", nlohmann::json{{"metrics", {metric("mean_speed", 11.0, "20 %", true)}}}.dump());
  nlohmann::json bad{{"metrics", {metric("mean_speed", 11.0, "20 %", true)}}};
  bad["metrics"][0]["value"] = "fast";
  const fs::path bad_value = writeFile("bad-value.json", bad.dump());
  EXPECT_THAT(inputErrorOf([&] { diffMetricFiles(good, bad_value); }), HasSubstr("bad-value.json: key 'metrics[0].value': wrong type; got \"fast\" (string)"));
  bad["metrics"][0]["value"] = 11.0;
  bad["metrics"][0]["tolerance"] = "a lot %";
  const fs::path bad_tolerance = writeFile("bad-tolerance.json", bad.dump());
  EXPECT_THAT(inputErrorOf([&] { diffMetricFiles(bad_tolerance, good); }), HasSubstr("bad-tolerance.json: key 'metrics[0].tolerance'"));
  const fs::path no_list = writeFile("no-list.json", R"({"metric": []})");
  EXPECT_THAT(inputErrorOf([&] { diffMetricFiles(good, no_list); }), HasSubstr("no-list.json: key 'metrics': missing field"));
}

TEST(Diff, CompareMetricsWithoutCaseAreDiffed) {
  // compare's metrics.json names no case: 11 -> 14 um/s is 27 %, beyond the 20 % tolerance.
  const fs::path a = writeFile("compare-a.json", nlohmann::json{{"schema", "mmval-compare/1"}, {"metrics", {metric("mean_speed", 11.0, "20 %", true)}}}.dump());
  const fs::path b = writeFile("compare-b.json", nlohmann::json{{"schema", "mmval-compare/1"}, {"metrics", {metric("mean_speed", 14.0, "20 %", false)}}}.dump());
  const std::string table = diffMetricFiles(a, b);
  EXPECT_THAT(table, HasSubstr("| /mean_speed | 11 | 14 | +27.3 % | 20 % | pass | FAIL |"));
  EXPECT_EQ(diffMetricFiles(a, a), "No metric changed beyond its tolerance.\n");
}

TEST(Diff, OwnAndPeerRunsOfOneCaseAreDiffedSolverBySolver) {
  // validate runs a peer-tagged case twice under one case name: mmval's solver and OpenFOAM
  // (k 1.93672e-10 and 1.94086e-10 m2 for square-array-phi020, 0.21 % apart). Unchanged
  // runs must diff to nothing, not to one solver against the other.
  auto doc = [](double ours, double peer) {
    nlohmann::json a = metric("permeability", ours, "0.1 %", true), b = metric("permeability", peer, "0.1 %", true);
    a["case"] = b["case"] = "square-array-phi020";
    a["solver"] = "mmval simulate";
    b["solver"] = "openfoam v1912";
    return nlohmann::json{{"schema", "mmval-metrics/1"}, {"metrics", {a, b}}};
  };
  EXPECT_EQ(diffMetrics(doc(1.93672, 1.94086), doc(1.93672, 1.94086)), "No metric changed beyond its tolerance.\n");
  // The peer's value moves by 1 %, beyond its 0.1 %: only the peer's row, named by its solver.
  const std::string table = diffMetrics(doc(1.93672, 1.94086), doc(1.93672, 1.94086 * 1.01));
  EXPECT_THAT(table, HasSubstr("| square-array-phi020 [openfoam v1912]/permeability | 1.94086 | 1.96027 | +1 % | 0.1 % | pass | pass |"));
  EXPECT_THAT(table, ::testing::Not(HasSubstr("mmval simulate")));
}

}  // namespace
}  // namespace mmval::reports
