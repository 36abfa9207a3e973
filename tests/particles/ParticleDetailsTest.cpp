// The details the particle kinds write follow their declarations
// (mmval/core/DetailFields.hpp): a particles-resolved and a particles-micromodel
// run, each on the cheapest scene that still exercises the fields, write no
// declared field in another type (checkDetails on result.json as written), and
// the fields two kinds share (coupling, warnings) read back through the typed
// accessors with the values the case sets. The Table 3 cases say which case
// of the paper they are (analysis.table3_case), and a run writes it.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>

#include <nlohmann/json.hpp>

#include "../TestScratch.hpp"
#include "ParticleRegistry.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/DetailFields.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/particles/EngineFactory.hpp"

namespace mmval::particles {
namespace {

namespace fs = std::filesystem;
using F = DetailField;

/// Runs `text` as `mmval run` does and returns result.json as written to disk.
nlohmann::json runAndRead(const std::string& text, const std::string& name) {
  CaseKindRegistry& reg = test_support::particleRegistry();
  const fs::path dir = test::scratch(name);
  const Case c = Case::parse(text, dir.string() + ".toml", reg);
  const RunSummary s = runCase(c, reg, dir, {.quiet = true});
  std::ifstream in(s.result_file);
  return nlohmann::json::parse(in);
}

/// checkDetails throws on a declared field of another type; it must not.
void expectDeclaredTypes(const nlohmann::json& result, const std::string& name) {
  const nlohmann::json& d = resultDetails(result);
  ASSERT_TRUE(d.is_object()) << name;
  EXPECT_NO_THROW(checkDetails(d, name + "/result.json")) << d.dump(1);
  EXPECT_FALSE(d.contains("warning")) << "warnings are a list (details.warnings)";
  EXPECT_FALSE(d.contains("undeclared_metrics")) << d["undeclared_metrics"].dump();
}

// One 10 um disk settling in a 100 x 40 um box at 5 cells per diameter (2 um cells):
// below the ~8 cells a resolved particle needs, so the run must warn.
constexpr const char* kResolved = R"(
[case]
name = "details-resolved"
kind = "particles-resolved"
[channel]
length = "100 um"
width = "40 um"
[particles]
diameter = "10 um"
x = ["50 um"]
y = ["20 um"]
[physics]
gravity_x = "-9.81 m/s2"
[numerics]
cells_per_diameter = 5
max_step_fraction = 1.0
[run]
duration = "0.2 s"
output_interval = "0.1 s"
)";

TEST(ParticleDetails, ResolvedRunWritesCouplingAndWarningsAsDeclared) {
  const nlohmann::json r = runAndRead(kResolved, "details-resolved");
  expectDeclaredTypes(r, "details-resolved");
  const nlohmann::json& d = resultDetails(r);
  const auto coupling = detailObject(d, F::coupling);
  ASSERT_TRUE(coupling.has_value()) << d.dump(1);
  EXPECT_EQ(detailString(*coupling, F::coupling_mode), "resolved");
  EXPECT_EQ(detailInteger(*coupling, F::coupling_cells_per_diameter), 5);
  // The grid spans the box at 10 um / 5 = 2 um per cell: 100 / 2 = 50 by 40 / 2 = 20 cells
  // (+-1: the axis may round the last cell).
  const nlohmann::json& cells = coupling->value->at("fluid_grid_cells");
  ASSERT_EQ(cells.size(), 2U);
  EXPECT_NEAR(cells[0].get<double>(), 50.0, 1.0);
  EXPECT_NEAR(cells[1].get<double>(), 20.0, 1.0);
  const auto warnings = detailStrings(d, F::warnings);
  ASSERT_TRUE(warnings.has_value()) << d.dump(1);
  ASSERT_EQ(warnings->size(), 1U);
  EXPECT_NE(warnings->front().find("5 cells per diameter"), std::string::npos) << warnings->front();
  EXPECT_EQ(detailInteger(d, F::resumed_from_frame), 0);
}

/// 60 x 30 px at 5 um/px (0.3 x 0.15 mm), two round grains; 0 = grain, 255 = pore.
fs::path grainsMask() {
  const fs::path file = test::scratch("details-grains.pgm");
  std::ofstream f(file, std::ios::binary);
  const int cols = 60, rows = 30;
  f << "P5\n" << cols << " " << rows << "\n255\n";
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const bool grain = std::hypot(c - 20, r - 10) < 5 || std::hypot(c - 40, r - 20) < 6;
      f.put(static_cast<char>(grain ? 0 : 255));
    }
  return file;
}

std::string micromodelText(const fs::path& mask) {
  return "[case]\nname = \"details-micromodel\"\nkind = \"particles-micromodel\"\n"
         "[geometry]\nmask = \"" + mask.string() + "\"\npixel_size = \"5 um\"\ndepth = \"20 um\"\n"
         "[flow]\nrate = \"20 uL/min\"\n"
         "[particles]\ndiameter = \"5 um\"\ncount = 60\n"
         "[coupling]\nmode = \"four-way\"\n"
         "[numerics]\ncells_per_pixel = 0.5\n"
         "[analysis]\ntable3_case = \"III\"\n"
         "[run]\nduration = \"2 s\"\noutput_interval = \"0.1 s\"\ncheckpoint_every = 0\n";
}

TEST(ParticleDetails, MicromodelRunWritesCouplingAndTheTable3CaseAsDeclared) {
  const nlohmann::json r = runAndRead(micromodelText(grainsMask()), "details-micromodel");
  expectDeclaredTypes(r, "details-micromodel");
  const nlohmann::json& d = resultDetails(r);
  EXPECT_EQ(detailString(d, F::table3_case), "III");
  const auto coupling = detailObject(d, F::coupling);
  ASSERT_TRUE(coupling.has_value()) << d.dump(1);
  EXPECT_EQ(detailString(*coupling, F::coupling_mode), "four-way");
  // Every deposit is booked once, at a grain or on a plate: their sum is the run's retained count.
  const auto at_walls = detailInteger(*coupling, F::coupling_deposits_at_walls);
  const auto on_plates = detailInteger(*coupling, F::coupling_deposits_on_plates);
  ASSERT_TRUE(at_walls && on_plates) << coupling->value->dump();
  double retained = NAN;
  for (const auto& m : r["metrics"])
    if (m["name"] == "retained") retained = m["value"].get<double>();
  // 60 particles over 2 s: 5 retained with the stream-function near-wall layer (30 over 1 s: none).
  EXPECT_GT(retained, 0.0) << "the scene must deposit something for the sum to test anything";
  EXPECT_EQ(static_cast<double>(*at_walls + *on_plates), retained);
  // cells_per_pixel 0.5 on a 60 x 30 px mask: 30 x 15 fluid cells.
  EXPECT_EQ(coupling->value->at("fluid_grid_cells"), nlohmann::json::array({30, 15}));
  // The run ended at its end time (no pump limit set).
  EXPECT_NEAR(detailNumber(d, F::end_time_s).value_or(-1), 2.0, 1e-9);
}

TEST(ParticleDetails, Table3CasesNameTheirCase) {
  CaseKindRegistry& reg = test_support::particleRegistry();
  const std::map<std::string, std::string> numeral{{"i", "I"}, {"ii", "II"}, {"iii", "III"}, {"iv", "IV"}, {"v", "V"}};
  for (const auto& [suffix, roman] : numeral) {
    const fs::path file = fs::path(MMVAL_SOURCE_DIR) / "cases" / ("particles-table3-" + suffix + ".toml");
    SCOPED_TRACE(file.filename().string());
    const Case c = Case::load(file, reg);
    ASSERT_TRUE(c.has("analysis.table3_case"));
    EXPECT_EQ(c.text("analysis.table3_case"), roman);
  }
}

// Two particles through a short channel with the LIGGGHTS engine (softened to a
// 1.4e-7 s DEM step, ~4e4 steps): the run records the LIGGGHTS version, which
// the report's provenance block shows. The first interval has no particle yet
// (injection spreads them over 5 ms), which LIGGGHTS must not be run on.
constexpr const char* kLiggghtsChannel = R"(
[case]
name = "details-liggghts-channel"
kind = "particles-channel"
[channel]
length = "400 um"
width = "100 um"
depth = "20 um"
mean_velocity = "0.7 mm/s"
[particles]
diameter = "5 um"
count = 2
injection_time = "0.005 s"
engine = "liggghts"
youngs_modulus = "1e5 Pa"
[run]
duration = "0.01 s"
output_interval = "0.005 s"
)";

TEST(ParticleDetails, LiggghtsChannelRunRecordsTheLiggghtsVersion) {
  if (!liggghtsAvailable()) GTEST_SKIP() << "this build has no LIGGGHTS engine";
  const nlohmann::json r = runAndRead(kLiggghtsChannel, "details-liggghts-channel");
  expectDeclaredTypes(r, "details-liggghts-channel");
  const nlohmann::json& d = resultDetails(r);
  EXPECT_EQ(d.value("engine", ""), "liggghts");
  const auto version = detailString(d, F::liggghts_version);
  ASSERT_TRUE(version.has_value()) << d.dump(1);
  EXPECT_EQ(version->rfind("LIGGGHTS", 0), 0u) << *version;
}

}  // namespace
}  // namespace mmval::particles
