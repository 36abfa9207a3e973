// MetricResult's typed fields: an acceptance entry with a label gives the
// declared metric, the label, the source's citation / locator / doi and the
// setting its reference describes as separate fields of result.json, next to
// the display name and display source the tables show.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "mmval/core/Case.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/ReferenceData.hpp"
#include "../TestScratch.hpp"

namespace mmval {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

const fs::path kDir = fs::path(MMVAL_SOURCE_DIR) / "reference-data";

/// An acceptance entry for c_D against a reference-data row, within 5 %.
Acceptance dragEntry(const std::string& file, const AtMap& at, const std::string& label) {
  Acceptance a;
  a.metric = "c_D";
  a.label = label;
  a.reference = lookupReference(kDir / file, "c_D", at, {"case.toml", 1, 0, "acceptance[0].reference"});
  a.tolerance = {Tolerance::Kind::relative, 0.05, "5 %"};
  a.reason = "test";
  return a;
}

TEST(MetricResult, LabelledEntryGivesMetricLabelAndSourceSeparately) {
  // Dennis & Chang (1970), J. Fluid Mech. 42(3), 471-489: c_D = 2.045 at Re = 20.
  const MetricResult m = evaluateMetric(dragEntry("cylinder-drag-dennis-chang.toml", {{"Re", 20.0}}, "Dennis & Chang"), 2.10);
  EXPECT_EQ(m.name, "c_D (Dennis & Chang)");  // the display name the tables show
  EXPECT_EQ(m.metric, "c_D");
  EXPECT_EQ(m.label, "Dennis & Chang");
  ASSERT_TRUE(m.reference.has_value());
  EXPECT_NEAR(m.reference->value, 2.045, 1e-12);
  EXPECT_NEAR(m.error, (2.10 - 2.045) / 2.045, 1e-12);
  const nlohmann::json j = m.toJson();
  EXPECT_EQ(j["name"], "c_D (Dennis & Chang)");
  EXPECT_EQ(j["metric"], "c_D");
  EXPECT_EQ(j["label"], "Dennis & Chang");
  EXPECT_EQ(j["unit"], "1");
  EXPECT_EQ(j["dimension"], "1");
  EXPECT_THAT(j["source_ref"]["citation"].get<std::string>(), ::testing::StartsWith("S. C. R. Dennis, G.-Z. Chang (1970)"));
  EXPECT_EQ(j["source_ref"]["locator"], "");
  EXPECT_EQ(j["source_ref"]["doi"], "10.1017/S0022112070001428");
  EXPECT_THAT(j["source"].get<std::string>(), HasSubstr("doi:10.1017/S0022112070001428"));  // the display string stays
  EXPECT_EQ(j["reference_setup"], "unbounded-cylinder");
  EXPECT_TRUE(j["pass"].get<bool>());
}

TEST(MetricResult, SetupAndLocatorComeFromTheReferenceFile) {
  // The paper's own column of Table 1 (2.13 at Re = 20), with its locator.
  const MetricResult paper =
      evaluateMetric(dragEntry("cylinder-drag-paper-table1.toml", {{"Re", 20.0}, {"column", std::string("this paper")}}, "paper model"), 2.10);
  const nlohmann::json p = paper.toJson();
  EXPECT_EQ(p["reference_setup"], "unbounded-cylinder");
  EXPECT_THAT(p["source_ref"]["locator"].get<std::string>(), HasSubstr("Table 1"));
  EXPECT_EQ(p["source_ref"]["doi"], "10.1016/j.powtec.2022.117130");
  // Schaefer & Turek 2D-1 (John & Matthies 2001: 5.57953523384), no label: a channel.
  const MetricResult st = evaluateMetric(dragEntry("schaefer-turek-2d.toml", {{"case", std::string("2D-1")}}, ""), 5.58);
  EXPECT_EQ(st.name, "c_D");
  EXPECT_EQ(st.toJson()["label"], "");
  EXPECT_EQ(st.toJson()["reference_setup"], "confined-channel-cylinder");
}

TEST(MetricResult, RunnerSetNameOnlyIsItsOwnMetricAndHasNoSource) {
  MetricResult m;
  m.name = "mean_speed";
  m.unit = "um/s";
  m.value = 12.5;
  const nlohmann::json j = m.toJson();
  EXPECT_EQ(j["metric"], "mean_speed");
  EXPECT_EQ(j["label"], "");
  EXPECT_EQ(j["dimension"], "m s^-1");
  EXPECT_FALSE(j.contains("source_ref"));
  EXPECT_FALSE(j.contains("reference_setup"));
}

TEST(ReferenceSetup, ABadSetupNameIsAnInputErrorNamingTheKey) {
  const fs::path file = test::scratch("bad-setup.toml");
  fs::create_directories(file.parent_path());
  std::ofstream(file) << "format = \"mmval-reference/1\"\ntitle = \"t\"\ndescription = \"d\"\nsetup = \"Unbounded Cylinder\"\n"
                         "[[sources]]\nid = \"s\"\ncitation = \"c\"\n[[rows]]\nquantity = \"c_D\"\nvalue = 1.0\nunit = \"1\"\nsource = \"s\"\n";
  try {
    loadReferenceFile(file);
    FAIL() << "no InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(std::string(e.what()), HasSubstr("bad-setup.toml:4"));
    EXPECT_THAT(std::string(e.what()), HasSubstr("setup"));
    EXPECT_THAT(std::string(e.what()), HasSubstr("Unbounded Cylinder"));
  }
}

}  // namespace
}  // namespace mmval
