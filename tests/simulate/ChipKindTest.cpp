// The chip-generator case kind: its metrics are chip.json's numbers (read back from the file it
// wrote, independently of the kind), and a bad key is refused naming the case key.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "mmval/core/Error.hpp"
#include "mmval/core/Run.hpp"

#include "../ResultJson.hpp"
#include "../TestScratch.hpp"
#include "FluidRegistry.hpp"

namespace fs = std::filesystem;
using namespace mmval;

namespace {

/// A tiny chip (75 x 50 px, no k target: the grain scale is estimated, one ladder of two levels).
std::string tinyChip(const std::string& geometry = "min_throat_px = 2\n") {
  return "[case]\nname = \"tiny-chip\"\nkind = \"chip-generator\"\n"
         "[geometry]\nlength = \"0.3 mm\"\nwidth = \"0.2 mm\"\npixel_size = \"4 um\"\ndepth = \"20 um\"\n" +
         geometry +
         "[target]\nporosity = 0.65\n[grains]\nmean_diameter = \"40 um\"\n[numerics]\ntile = \"0.2 mm\"\ncells_per_pixel = 1\nladder = [0.5, 1, 2]\n";
}

using mmval::test::metricOf;
using mmval::test::readJson;

}  // namespace

TEST(ChipKind, MetricsAreTheChipJsonItWrote) {
  const auto& registry = test_support::fluidRegistry();
  const Case c = Case::parse(tinyChip(), test::scratch("tiny-chip.toml"), registry);
  const fs::path out = test::scratch("tiny-chip-run");
  fs::remove_all(out);
  runCase(c, registry, out, {true, false});
  for (const char* f : {"chip.png", "chip.json", "chip-picture.png", "grain-sizes.csv", "throat-sizes.csv", "result.json"})
    EXPECT_TRUE(fs::exists(out / f)) << f;
  const nlohmann::json chip = readJson(out / "chip.json");
  const nlohmann::json result = readJson(out / "result.json");
  // Written with full precision: equal to round-off.
  auto expectNear = [&](const std::string& metric, double expected, const std::string& unit) {
    const double got = metricOf(result, metric);
    EXPECT_NEAR(got, expected, 1e-9 * std::abs(expected)) << metric << " (" << unit << ")";
  };
  EXPECT_EQ(chip["image"]["cols"].get<int>(), 75);
  EXPECT_EQ(chip["image"]["rows"].get<int>(), 50);
  expectNear("porosity_connected", chip["porosity"]["connected"].get<double>(), "1");
  EXPECT_NEAR(chip["porosity"]["connected"].get<double>(), 0.65, 0.005);  // the generator's default tolerance
  const auto& da = chip["permeability"]["depth_averaged"];
  // The ladder's level at cells_per_pixel 1 is the second run.
  ASSERT_EQ(da["runs"].size(), 3u);
  EXPECT_DOUBLE_EQ(da["runs"][1]["cells_per_pixel"].get<double>(), 1.0);
  // result.json gives each metric in its declared display unit.
  const auto unitOf = [&](const std::string& metric) {
    for (const auto& m : result.at("metrics"))
      if (m.at("name") == metric) return m.value("unit", std::string());
    return std::string();
  };
  EXPECT_EQ(unitOf("permeability_depth_averaged"), "D");
  EXPECT_EQ(unitOf("mean_throat_radius"), "um");
  const double k_level = chip["targets"]["permeability_depth_averaged_D"]["achieved"].get<double>();
  expectNear("permeability_depth_averaged", k_level, "D");
  // The same chip at the same level as the ladder's second run: the same solve (1e-6: solver round-off).
  EXPECT_NEAR(k_level, da["runs"][1]["permeability_D"].get<double>(), 1e-6 * k_level);
  if (da["extrapolated_D"].is_number()) expectNear("permeability_depth_averaged_extrapolated", da["extrapolated_D"].get<double>(), "D");
  if (da["gci"].is_number()) expectNear("permeability_depth_averaged_gci", da["gci"].get<double>(), "1");
  expectNear("mean_throat_radius", chip["throats"]["mean_radius_um"].get<double>(), "um");
  expectNear("median_throat_radius", 0.5 * chip["throats"]["median_width_um"].get<double>(), "um");
  expectNear("grains", chip["grains"]["count"].get<double>(), "1");
  expectNear("mean_grain_diameter", chip["grains"]["mean_diameter_um"].get<double>(), "um");
}

TEST(ChipKind, BadKeyIsAnInputErrorNamingIt) {
  const auto& registry = test_support::fluidRegistry();
  // A ladder without the target level: refused by the generator's check, reported at the case key.
  Case c = Case::parse(tinyChip(), test::scratch("bad-chip.toml"), registry);
  c.set("numerics.cells_per_pixel", 0.75);
  try {
    registry.find("chip-generator")->run(c, RunContext{{}, true, false, 0});
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().key, "numerics.ladder") << e.what();
  }
  // A value outside the declared range: refused when the file is read.
  try {
    Case::parse(tinyChip("min_throat_px = 1\n"), test::scratch("bad-chip2.toml"), registry);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("geometry.min_throat_px"), std::string::npos) << e.what();
  }
}
