// Case files: malformed inputs give an error naming file, line and key;
// valid ones resolve defaults and units; acceptance entries resolve into
// reference-data and evaluate against tolerances.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "mmval/core/Case.hpp"
#include "mmval/core/CaseKind.hpp"
#include "mmval/core/Run.hpp"

namespace mmval {
namespace {

using ::testing::HasSubstr;

/// A small kind exercising every key type. Its runner reports the plane
/// Poiseuille flow rate per unit width, q = G h^3 / (12 mu), so run tests
/// compare a computed value against a hand-computed one.
CaseKindRegistry& registry() {
  static CaseKindRegistry r = [] {
    CaseKindRegistry reg;
    CaseKind k;
    k.name = "slot";
    k.summary = "test kind: plane Poiseuille flow in a slot";
    k.declare = [](Schema& s) {
      s.quantity("fluid.viscosity", "Pa s", "Dynamic viscosity").def("1e-3 Pa s").positive();
      s.quantity("fluid.density", "kg/m3", "Density").def("1000 kg/m3").positive();
      s.quantity("geometry.gap", "um", "Gap between the plates").positive();
      s.quantity("flow.pressure_gradient", "Pa/m", "Driving pressure gradient").def("1e4 Pa/m");
      s.quantity("flow.injection_rate", "uL/min", "Pump rate").optional().nonNegative();
      s.quantity("particles.fraction", "1", "Volume fraction").def(0.01).fraction();
      s.quantityList("particles.diameters", "um", "Diameters").def(std::vector<double>{5e-6}).positive();
      s.integer("numerics.cells", "Cells across the gap").def(32).min(4).max(4096);
      s.choice("numerics.scheme", {"stokes", "navier-stokes"}, "Model").def("stokes");
      s.boolean("numerics.verbose", "Chatty").def(false);
      s.path("geometry.mask", "Mask image").optional();
      s.realList("numerics.levels", "Ladder").def(std::vector<double>{});
    };
    k.run = [](const Case& c, const RunContext&) {
      RunOutput out;
      const double h = c.quantity("geometry.gap");
      out.metrics["flow_rate_per_width"] = c.quantity("flow.pressure_gradient") * h * h * h / (12 * c.quantity("fluid.viscosity"));
      out.units["flow_rate_per_width"] = "m2/s";
      out.metrics["cells"] = static_cast<double>(c.integer("numerics.cells"));
      return out;
    };
    reg.add(k);
    return reg;
  }();
  return r;
}

const char* kValid = R"([case]
name = "slot-test"
kind = "slot"

[geometry]
gap = "20 um"

[fluid]
viscosity = "1 cP"
)";

std::string errorOf(const std::string& text, const std::string& file = "cases/bad.toml") {
  try {
    Case::parse(text, file, registry());
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

// --- valid files --------------------------------------------------------

TEST(CaseFile, ValidFileResolvesUnitsAndDefaults) {
  const Case c = Case::parse(kValid, "cases/slot.toml", registry());
  EXPECT_EQ(c.name(), "slot-test");
  EXPECT_EQ(c.kind(), "slot");
  EXPECT_DOUBLE_EQ(c.quantity("geometry.gap"), 20e-6);
  EXPECT_DOUBLE_EQ(c.quantity("fluid.viscosity"), 1e-3);
  EXPECT_DOUBLE_EQ(c.quantity("fluid.density"), 1000.0);
  EXPECT_EQ(c.integer("numerics.cells"), 32);
  EXPECT_EQ(c.text("numerics.scheme"), "stokes");
  EXPECT_FALSE(c.has("flow.injection_rate"));
  EXPECT_FALSE(c.has("geometry.mask"));
  EXPECT_EQ(c.where("geometry.gap").line, 6);
  EXPECT_EQ(c.where("numerics.cells").line, 0);  // from the default
}

TEST(CaseFile, PathsResolveAgainstTheCaseFolder) {
  const std::string text = "[case]\nname = \"x\"\nkind = \"slot\"\n[geometry]\ngap = 2e-5\nmask = \"masks/chip.png\"\n";
  const Case c = Case::parse(text, "cases/sub/slot.toml", registry());
  EXPECT_EQ(c.path("geometry.mask"), std::filesystem::path("cases/sub/masks/chip.png"));
  EXPECT_DOUBLE_EQ(c.quantity("geometry.gap"), 2e-5);  // bare numbers are SI
}

TEST(CaseFile, ResolvedJsonCarriesDisplayUnitsAndHashIsStable) {
  const Case a = Case::parse(kValid, "cases/slot.toml", registry());
  const Case b = Case::parse(std::string(kValid) + "\n# a comment changes nothing\n", "cases/slot.toml", registry());
  EXPECT_EQ(a.resolvedJson()["geometry"]["gap"], "20 um");
  EXPECT_EQ(a.resolvedJson()["numerics"]["cells"], 32);
  EXPECT_EQ(a.hash(), b.hash());
  const Case c = Case::parse(std::string(kValid) + "[numerics]\ncells = 64\n", "cases/slot.toml", registry());
  EXPECT_NE(a.hash(), c.hash());
  EXPECT_EQ(a.hash().size(), 16u);
}

// --- malformed files: each names file, line and key ---------------------

TEST(CaseFileErrors, UnknownKeySuggestsNearest) {
  const std::string e = errorOf(std::string(kValid) + "viscosty = 2\n");
  // "viscosty" lands in [fluid] (the last table), line 10.
  EXPECT_THAT(e, HasSubstr("cases/bad.toml:10"));
  EXPECT_THAT(e, HasSubstr("fluid.viscosty"));
  EXPECT_THAT(e, HasSubstr("did you mean 'fluid.viscosity'"));
}

TEST(CaseFileErrors, UnknownTableSuggestsNearest) {
  const std::string e = errorOf(std::string(kValid) + "[numerix]\ncells = 8\n");
  EXPECT_THAT(e, HasSubstr("numerix"));
  EXPECT_THAT(e, HasSubstr("did you mean 'numerics"));
}

TEST(CaseFileErrors, WrongDimension) {
  const std::string e = errorOf("[case]\nname = \"x\"\nkind = \"slot\"\n[geometry]\ngap = \"20 m/s\"\n");
  EXPECT_THAT(e, HasSubstr("cases/bad.toml:5"));
  EXPECT_THAT(e, HasSubstr("geometry.gap"));
  EXPECT_THAT(e, HasSubstr("wrong dimension"));
  EXPECT_THAT(e, HasSubstr("velocity"));
  EXPECT_THAT(e, HasSubstr("expected a length"));
}

TEST(CaseFileErrors, UnknownUnit) {
  const std::string e = errorOf("[case]\nname = \"x\"\nkind = \"slot\"\n[geometry]\ngap = \"20 mils\"\n");
  EXPECT_THAT(e, HasSubstr(":5"));
  EXPECT_THAT(e, HasSubstr("geometry.gap"));
  EXPECT_THAT(e, HasSubstr("mils"));
}

TEST(CaseFileErrors, MissingRequiredKey) {
  const std::string e = errorOf("[case]\nname = \"x\"\nkind = \"slot\"\n[fluid]\nviscosity = 1e-3\n");
  EXPECT_THAT(e, HasSubstr("cases/bad.toml"));
  EXPECT_THAT(e, HasSubstr("geometry.gap"));
  EXPECT_THAT(e, HasSubstr("missing required key"));
}

TEST(CaseFileErrors, MissingKind) {
  const std::string e = errorOf("[case]\nname = \"x\"\n");
  EXPECT_THAT(e, HasSubstr("case.kind"));
  EXPECT_THAT(e, HasSubstr("slot"));
}

TEST(CaseFileErrors, UnknownKindSuggestsNearest) {
  const std::string e = errorOf("[case]\nname = \"x\"\nkind = \"slit\"\n");
  EXPECT_THAT(e, HasSubstr(":3"));
  EXPECT_THAT(e, HasSubstr("did you mean 'slot'"));
}

TEST(CaseFileErrors, OutOfRangeValue) {
  const std::string e = errorOf(std::string(kValid) + "[numerics]\ncells = 2\n");
  EXPECT_THAT(e, HasSubstr("cases/bad.toml:11"));
  EXPECT_THAT(e, HasSubstr("numerics.cells"));
  EXPECT_THAT(e, HasSubstr("out of range"));
  EXPECT_THAT(e, HasSubstr(">= 4"));
}

TEST(CaseFileErrors, NegativeQuantityRejectedWithItsUnit) {
  const std::string e = errorOf("[case]\nname = \"x\"\nkind = \"slot\"\n[geometry]\ngap = \"-3 um\"\n");
  EXPECT_THAT(e, HasSubstr("geometry.gap"));
  EXPECT_THAT(e, HasSubstr("> 0 um"));
}

TEST(CaseFileErrors, FractionAbovePercentRange) {
  const std::string e = errorOf(std::string(kValid) + "[particles]\nfraction = \"120 %\"\n");
  EXPECT_THAT(e, HasSubstr("particles.fraction"));
  EXPECT_THAT(e, HasSubstr("<= 1"));
}

TEST(CaseFileErrors, BadTomlSyntaxGivesItsLine) {
  const std::string e = errorOf("[case]\nname = \"x\"\nkind = \"slot\"\n[geometry]\ngap = \"20 um\n");
  EXPECT_THAT(e, HasSubstr("cases/bad.toml:5"));
  EXPECT_THAT(e, HasSubstr("TOML syntax error"));
}

TEST(CaseFileErrors, WrongTypeForInteger) {
  const std::string e = errorOf(std::string(kValid) + "[numerics]\ncells = 12.5\n");
  EXPECT_THAT(e, HasSubstr("cases/bad.toml:11"));
  EXPECT_THAT(e, HasSubstr("numerics.cells"));
  EXPECT_THAT(e, HasSubstr("expected an integer"));
}

TEST(CaseFileErrors, ChoiceNotAllowedSuggestsNearest) {
  const std::string e = errorOf(std::string(kValid) + "[numerics]\nscheme = \"stoke\"\n");
  EXPECT_THAT(e, HasSubstr("numerics.scheme"));
  EXPECT_THAT(e, HasSubstr("did you mean 'stokes'"));
}

TEST(CaseFileErrors, ScalarWhereTableExpected) {
  const std::string e = errorOf("numerics = 3\n" + std::string(kValid));
  EXPECT_THAT(e, HasSubstr("cases/bad.toml:1"));
  EXPECT_THAT(e, HasSubstr("key 'numerics'"));
  EXPECT_THAT(e, HasSubstr("a table"));
}

TEST(CaseFileErrors, ListItemWithWrongDimensionNamesItsIndex) {
  const std::string e = errorOf(std::string(kValid) + "[particles]\ndiameters = [\"5 um\", \"10 s\"]\n");
  EXPECT_THAT(e, HasSubstr("particles.diameters[1]"));
  EXPECT_THAT(e, HasSubstr("wrong dimension"));
}

TEST(CaseFileErrors, AcceptanceWithoutReason) {
  const std::string e = errorOf(std::string(kValid) + "[[acceptance]]\nmetric = \"flow_rate_per_width\"\nreference = 1.0\ntolerance = \"1 %\"\n");
  EXPECT_THAT(e, HasSubstr("acceptance[0].reason"));
  EXPECT_THAT(e, HasSubstr("missing required key"));
}

TEST(CaseFileErrors, AcceptanceToleranceOfWrongDimension) {
  const std::string e = errorOf(std::string(kValid) +
                                "[[acceptance]]\nmetric = \"q\"\nreference = \"3 m2/s\"\ntolerance = \"1 s\"\nreason = \"r\"\n");
  EXPECT_THAT(e, HasSubstr("acceptance[0].tolerance"));
  EXPECT_THAT(e, HasSubstr("wrong dimension"));
}

TEST(CaseFileErrors, ReferencePointerToMissingRow) {
  const std::string text = std::string(kValid) +
                           "[[acceptance]]\nmetric = \"c_D\"\nreference = { file = \"../reference-data/schaefer-turek-2d.toml\", "
                           "quantity = \"c_D\", at = { case = \"2D-9\" } }\ntolerance = \"1 %\"\nreason = \"r\"\n";
  const std::string e = errorOf(text, std::string(MMVAL_SOURCE_DIR) + "/cases/bad.toml");
  EXPECT_THAT(e, HasSubstr("acceptance[0].reference"));
  EXPECT_THAT(e, HasSubstr("2D-9"));
}

// Fuzz finding (CI of 9270433): a reference name longer than the system's
// limit (NAME_MAX 255 on Linux) made std::filesystem::exists throw, and the
// case reader ended on an uncaught filesystem_error instead of an InputError.
TEST(CaseFileErrors, OverlongReferencePathIsAnInputError) {
  const std::string name = "../reference-data/" + std::string(600, 'a') + ".toml";
  const std::string text = std::string(kValid) + "[[acceptance]]\nmetric = \"c_D\"\nreference = { file = \"" + name +
                           "\", quantity = \"c_D\" }\ntolerance = \"1 %\"\nreason = \"r\"\n";
  const std::string e = errorOf(text, std::string(MMVAL_SOURCE_DIR) + "/cases/bad.toml");
  EXPECT_THAT(e, HasSubstr("acceptance[0].reference"));
}

TEST(CaseFileErrors, MissingFileIsAnInputError) {
  try {
    Case::load("no/such/case.toml", registry());
    FAIL();
  } catch (const InputError& e) {
    EXPECT_THAT(std::string(e.what()), HasSubstr("no/such/case.toml"));
  }
}

// --- acceptance ---------------------------------------------------------

TEST(Acceptance, ReferencePointerResolvesIntoReferenceData) {
  const std::string text = std::string(kValid) +
                           "[[acceptance]]\nmetric = \"c_D\"\nreference = { file = \"../reference-data/schaefer-turek-2d.toml\", "
                           "quantity = \"c_D\", at = { case = \"2D-1\" } }\ntolerance = \"0.5 %\"\nreason = \"grid\"\n";
  const Case c = Case::parse(text, std::string(MMVAL_SOURCE_DIR) + "/cases/st.toml", registry());
  ASSERT_EQ(c.acceptance().size(), 1u);
  const Acceptance& a = c.acceptance()[0];
  EXPECT_DOUBLE_EQ(a.reference.value, 5.57953523384);  // John & Matthies (2001)
  EXPECT_THAT(a.reference.source, HasSubstr("John"));
  EXPECT_DOUBLE_EQ(a.tolerance.value, 0.005);
  const MetricResult in = evaluateMetric(a, 5.59);
  EXPECT_TRUE(*in.pass);
  EXPECT_NEAR(in.error, (5.59 - 5.57953523384) / 5.57953523384, 1e-12);
  EXPECT_FALSE(*evaluateMetric(a, 5.62).pass);
}

TEST(Acceptance, IntervalAndAbsoluteTolerances) {
  const std::string text = std::string(kValid) +
                           "[[acceptance]]\nmetric = \"St\"\nreference = { file = \"../reference-data/schaefer-turek-2d.toml\", "
                           "quantity = \"St\", at = { case = \"2D-2\", from = \"interval\" } }\ntolerance = \"interval\"\nreason = \"benchmark interval\"\n"
                           "[[acceptance]]\nmetric = \"k\"\nreference = \"2.5 D\"\ntolerance = \"0.1 D\"\nreason = \"measurement\"\n";
  const Case c = Case::parse(text, std::string(MMVAL_SOURCE_DIR) + "/cases/st.toml", registry());
  const Acceptance& st = c.acceptance()[0];
  EXPECT_TRUE(*evaluateMetric(st, 0.30).pass);   // inside 0.295 - 0.305
  EXPECT_FALSE(*evaluateMetric(st, 0.31).pass);
  const Acceptance& k = c.acceptance()[1];
  EXPECT_EQ(k.reference.unit, "D");
  const MetricResult m = evaluateMetric(k, 2.58 * 9.869233e-13);
  EXPECT_TRUE(*m.pass);
  EXPECT_NEAR(m.value, 2.58, 1e-12);  // shown in darcy
  EXPECT_NEAR(m.error, 0.08, 1e-12);
  EXPECT_FALSE(*evaluateMetric(k, 2.65 * 9.869233e-13).pass);
  EXPECT_FALSE(*evaluateMetric(k, std::nan("")).pass);  // NaN never passes
}

TEST(Acceptance, NoneShowsTheReferenceAndItsErrorWithoutJudging) {
  // The 2D-2 interval (Schaefer & Turek 1996: c_L max 0.99 .. 1.01) and a point value, both "none".
  const std::string text = std::string(kValid) +
                           "[[acceptance]]\nmetric = \"c_L_max\"\nreference = { file = \"../reference-data/schaefer-turek-2d.toml\", "
                           "quantity = \"c_L_max\", at = { case = \"2D-2\", from = \"interval\" } }\ntolerance = \"none\"\nreason = \"context\"\n"
                           "[[acceptance]]\nmetric = \"k\"\nreference = \"2.5 D\"\ntolerance = \"none\"\nreason = \"context\"\n";
  const Case c = Case::parse(text, std::string(MMVAL_SOURCE_DIR) + "/cases/st.toml", registry());
  const Acceptance& cl = c.acceptance()[0];
  EXPECT_EQ(cl.tolerance.kind, Tolerance::Kind::none);
  ASSERT_TRUE(cl.reference.isInterval());  // kept as an interval, not reduced to its midpoint
  const MetricResult below = evaluateMetric(cl, 0.9852);
  EXPECT_FALSE(below.pass.has_value());
  EXPECT_NEAR(below.error, (0.9852 - 0.99) / 0.99, 1e-12);  // distance to the nearer bound
  EXPECT_EQ(evaluateMetric(cl, 1.0).error, 0.0);
  const nlohmann::json j = below.toJson();
  EXPECT_TRUE(j["pass"].is_null());
  EXPECT_EQ(j["tolerance"], "none");
  EXPECT_EQ(j["error_kind"], "relative");
  EXPECT_EQ(j["reference"], nlohmann::json::array({0.99, 1.01}));
  const MetricResult k = evaluateMetric(c.acceptance()[1], 2.6 * 9.869233e-13);
  EXPECT_FALSE(k.pass.has_value());
  EXPECT_NEAR(k.error, 0.04, 1e-12);  // relative error against the point value
}

TEST(Acceptance, TwoDTwoRowsAreSelectedByFrom) {
  const std::string head = std::string(kValid) +
                           "[[acceptance]]\nmetric = \"c_L_max\"\nreference = { file = \"../reference-data/schaefer-turek-2d.toml\", "
                           "quantity = \"c_L_max\", at = { case = \"2D-2\"";
  const std::string tail = " } }\ntolerance = \"0.3 %\"\nreason = \"r\"\n";
  const std::string file = std::string(MMVAL_SOURCE_DIR) + "/cases/st.toml";
  const Case c = Case::parse(head + ", from = \"FEATFLOW level 6\"" + tail, file, registry());
  EXPECT_DOUBLE_EQ(c.acceptance()[0].reference.value, 0.98658);  // FEATFLOW level 6, dt 1/1600
  EXPECT_THAT(c.acceptance()[0].reference.source, HasSubstr("FEATFLOW"));
  try {
    Case::parse(head + tail, file, registry());  // the interval and the computation both match
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(std::string(e.what()), HasSubstr("2 rows of 'c_L_max'"));
  }
}

// --- run ----------------------------------------------------------------

TEST(RunCase, WritesResultJsonAtomicallyWithMetricsAndProvenance) {
  // q = G h^3 / (12 mu) = 1e4 * (20e-6)^3 / (12 * 1e-3) = 8e-11 / 1.2e-2 = 6.6667e-9 m^2/s.
  const std::string text = std::string(kValid) +
                           "[[acceptance]]\nmetric = \"flow_rate_per_width\"\nreference = \"6.6666667e-9 m2/s\"\n"
                           "tolerance = \"0.01 %\"\nreason = \"closed form\"\n";
  const Case c = Case::parse(text, "cases/slot.toml", registry());
  const auto dir = std::filesystem::path(MMVAL_BINARY_DIR) / "test-output" / "run-slot";
  std::filesystem::remove_all(dir);
  const RunSummary s = runCase(c, registry(), dir, {true, false});
  EXPECT_TRUE(s.all_pass);
  EXPECT_TRUE(std::filesystem::exists(dir / "result.json"));
  EXPECT_FALSE(std::filesystem::exists(dir.string() + ".partial"));
  std::ifstream in(dir / "result.json");
  const auto j = nlohmann::json::parse(in);
  EXPECT_EQ(j["case"]["name"], "slot-test");
  EXPECT_EQ(j["case"]["hash"], c.hash());
  EXPECT_EQ(j["resolved_case"]["fluid"]["density"], "1000 kg/m3");
  ASSERT_GE(j["metrics"].size(), 2u);
  EXPECT_EQ(j["metrics"][0]["name"], "flow_rate_per_width");
  EXPECT_NEAR(j["metrics"][0]["value"].get<double>(), 6.6666667e-9, 1e-15);
  EXPECT_EQ(j["metrics"][0]["pass"], true);
  EXPECT_GT(j["cost"]["peak_memory_bytes"].get<double>(), 0.0);
  EXPECT_TRUE(j["provenance"].contains("git_hash"));
  EXPECT_TRUE(j["provenance"]["dependencies"].contains("petsc"));
}

TEST(RunCase, MissingMetricFails) {
  const std::string text = std::string(kValid) +
                           "[[acceptance]]\nmetric = \"nonexistent\"\nreference = 1.0\ntolerance = \"1 %\"\nreason = \"r\"\n";
  const Case c = Case::parse(text, "cases/slot.toml", registry());
  const auto dir = std::filesystem::path(MMVAL_BINARY_DIR) / "test-output" / "run-missing";
  const RunSummary s = runCase(c, registry(), dir, {true, false});
  EXPECT_FALSE(s.all_pass);
}

TEST(Schema, MarkdownListsEveryKeyWithUnitAndDefault) {
  const std::string md = registry().schema("slot").markdown();
  EXPECT_THAT(md, HasSubstr("`fluid.viscosity`"));
  EXPECT_THAT(md, HasSubstr("dynamic viscosity"));
  EXPECT_THAT(md, HasSubstr("`1e-3 Pa s`"));
  EXPECT_THAT(md, HasSubstr("**required**"));
  EXPECT_THAT(md, HasSubstr("one of stokes, navier-stokes"));
}

// --- command-line overrides (mmval run --set KEY=VALUE) --------------------

Case withSet(std::vector<std::string> sets, const std::string& text = kValid) {
  std::vector<CaseOverride> overrides;
  for (const auto& s : sets) overrides.push_back(CaseOverride::parse(s));
  return Case::parse(text, "cases/slot.toml", registry(), overrides);
}

std::string setErrorOf(std::vector<std::string> sets) {
  try {
    withSet(std::move(sets));
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(CaseOverride, ValuesReadAsTomlOrAsBareStrings) {
  const Case c = withSet({"geometry.gap=35 um", "fluid.viscosity=\"2 cP\"", "numerics.cells=64", "numerics.verbose=true",
                          "numerics.scheme=navier-stokes", "particles.diameters=[\"5 um\", \"10 um\"]", "flow.injection_rate=5 uL/min"});
  EXPECT_DOUBLE_EQ(c.quantity("geometry.gap"), 35e-6);       // replaces the file's 20 um
  EXPECT_DOUBLE_EQ(c.quantity("fluid.viscosity"), 2e-3);     // 2 cP
  EXPECT_EQ(c.integer("numerics.cells"), 64);
  EXPECT_TRUE(c.flag("numerics.verbose"));
  EXPECT_EQ(c.text("numerics.scheme"), "navier-stokes");
  ASSERT_EQ(c.reals("particles.diameters").size(), 2u);
  EXPECT_NEAR(c.reals("particles.diameters")[1], 10e-6, 1e-18);
  EXPECT_NEAR(c.quantity("flow.injection_rate"), 5e-9 / 60.0, 1e-22);  // a key the file does not have, in a table it lacks
  EXPECT_EQ(c.overrides().size(), 7u);
  EXPECT_THAT(c.where("numerics.cells").file, HasSubstr("--set numerics.cells=64"));
  EXPECT_NE(c.hash(), Case::parse(kValid, "cases/slot.toml", registry()).hash());
}

TEST(CaseOverride, BadValuesAreRefusedLikeTheCaseFileWouldRefuseThem) {
  EXPECT_THAT(setErrorOf({"numerics.cells=2"}), HasSubstr("cases/slot.toml (--set numerics.cells=2): key 'numerics.cells': value out of range"));
  EXPECT_THAT(setErrorOf({"fluid.viscosity=1 m/s"}), HasSubstr("key 'fluid.viscosity': wrong dimension"));
  EXPECT_THAT(setErrorOf({"numerics.cells=many"}), HasSubstr("key 'numerics.cells': wrong type"));
  EXPECT_THAT(setErrorOf({"numerics.scheme=stoks"}), HasSubstr("did you mean 'stokes'"));
  EXPECT_THAT(setErrorOf({"fluid.viscosty=1 cP"}), HasSubstr("did you mean 'fluid.viscosity'"));
  EXPECT_THAT(setErrorOf({"fluid=1"}), HasSubstr("key 'fluid': a table, not a key"));
  EXPECT_THAT(setErrorOf({"geometry.gap.x=1"}), HasSubstr("'geometry.gap' is a value in the case file, not a table"));
  EXPECT_THAT(setErrorOf({"numerics.cells.x=1"}), HasSubstr("key 'numerics.cells.x': unknown key for kind 'slot'"));
  EXPECT_THAT(setErrorOf({"numerics.cells"}), HasSubstr("no '=' between key and value"));
  EXPECT_THAT(setErrorOf({"=3"}), HasSubstr("no key before '='"));
  EXPECT_THAT(setErrorOf({"numerics..cells=3"}), HasSubstr("empty part in the key"));
  EXPECT_THAT(setErrorOf({"acceptance.metric=x"}), HasSubstr("[[acceptance]] entries cannot be set"));
  EXPECT_EQ(setErrorOf({"numerics.cells=4"}), "(no error)");  // the bound itself is allowed (>= 4)
}

}  // namespace
}  // namespace mmval
