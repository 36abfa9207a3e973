// Rectangular-duct flow (DuctFlow.hpp): the exact series against the reference file's values
// (Bruus 2008, reference-data/shallow-channels.toml), the depth-averaged model's closed form, the
// excess of one over the other, and the image kind's report of that excess at the narrowest throat
// of a mask (one small depth-averaged solve, well under a second).
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "mmval/core/Case.hpp"
#include "mmval/core/CaseKind.hpp"
#include "mmval/core/ReferenceData.hpp"
#include "mmval/simulate/DuctFlow.hpp"
#include "mmval/simulate/Kinds.hpp"
#include "mmval/simulate/PoreSpace.hpp"

#include "../TestScratch.hpp"
#include "FluidRegistry.hpp"

namespace fs = std::filesystem;
using namespace mmval;
using namespace mmval::simulate;

namespace {

const ReferenceFile& channels() { return loadReferenceFile(fs::path(MMVAL_SOURCE_DIR) / "reference-data" / "shallow-channels.toml"); }

/// A 20 x 40 px channel of pore with a one-pixel wall across column 20 pierced in its middle by a
/// slot of `slot` pixels (grains black, pores white, 8-bit PGM).
fs::path slotMask(int slot, const std::string& name) {
  const int rows = 20, cols = 40;
  const fs::path p = mmval::test::scratch(name);
  std::ofstream f(p, std::ios::binary);
  f << "P5\n" << cols << " " << rows << "\n255\n";
  for (int i = 0; i < rows; ++i)
    for (int j = 0; j < cols; ++j) {
      const int row0 = (rows - slot) / 2;
      const bool grain = j == 20 && !(i >= row0 && i < row0 + slot);
      f.put(static_cast<char>(grain ? 0 : 255));
    }
  return p;
}

RunOutput runSlot(int slot, const std::string& depth_model) {
  const CaseKindRegistry& reg = test_support::fluidRegistry();
  const fs::path mask = slotMask(slot, "duct-slot-" + std::to_string(slot) + ".pgm");
  const std::string text = "[case]\nname = \"slot\"\nkind = \"image-permeability\"\n[geometry]\nmask = \"" + mask.generic_string() +
                           "\"\npixel_size = \"10 um\"\ngrains = \"dark\"\ndepth = \"20 um\"\n[numerics]\ncells_per_pixel = 1.0\ndepth_model = \"" +
                           depth_model + "\"\n";
  const Case c = Case::parse(text, mask.parent_path() / "slot.toml", reg);
  return reg.find(c.kind())->run(c, RunContext{{}, true, false, 0});
}

bool hasWarningWith(const RunOutput& out, const std::string& words) {
  if (!out.details.contains("warnings")) return false;
  for (const auto& w : out.details["warnings"])
    if (w.get<std::string>().find(words) != std::string::npos) return true;
  return false;
}

}  // namespace

TEST(DuctFlow, ExactSeriesMatchesTheReferenceFile) {
  // Every rectangular-duct row of the reference file (h / w = 0.05 .. 1), 4 digits as given there.
  int rows = 0;
  for (const ReferenceRow* r : channels().find("flow_rate_factor", {{"geometry", std::string("rectangular duct")}})) {
    const double hw = std::get<double>(r->at.at("h_over_w"));
    EXPECT_NEAR(ductFlowFactorExact(1.0, hw), *r->value, 6e-5) << "h/w " << hw;
    ++rows;
  }
  EXPECT_GE(rows, 5);
}

TEST(DuctFlow, DeepDuctIsTheShallowOneTurnedOnItsSide) {
  // Q is symmetric in w and h: Q(w, h) / (w h^3) and Q(h, w) / (h w^3) differ by (w/h)^2 exactly.
  for (const double r : {0.1, 0.3, 0.5, 0.8}) EXPECT_NEAR(ductFlowFactorExact(r, 1.0), ductFlowFactorExact(1.0, r) * r * r, 1e-12) << r;
  // A square duct: the reference value 0.4217 either way round.
  EXPECT_NEAR(ductFlowFactorExact(2.0, 2.0), 0.4217, 6e-5);
  // Very deep and narrow: plane Poiseuille across the width, Q -> h w^3 G / (12 mu) (1 - 0.630 w / h).
  EXPECT_NEAR(ductFlowFactorExact(1.0, 100.0) * 1e4, 1 - 192 / std::pow(M_PI, 5) * 1.00452 * 0.01, 1e-4);
}

TEST(DuctFlow, DepthAveragedModelAndItsExcess) {
  // Closed form of the Brinkman-Hele-Shaw duct (the channel kind checks its solver against it):
  // w = 10 h gives 0.9423, the value the shallow-duct case states (+0.56 % over 0.9370).
  EXPECT_NEAR(ductFlowFactorDepthAveraged(10.0, 1.0), 0.9423, 6e-5);
  EXPECT_NEAR(depthAveragedDuctExcess(10.0, 1.0), 0.9423 / 0.9370 - 1, 2e-4);
  // The excess grows as the duct narrows: +8.5 % for a square duct, ~+12 % at w = h / 2.
  EXPECT_NEAR(depthAveragedDuctExcess(1.0, 1.0), 0.4577 / 0.4217 - 1, 5e-4);
  EXPECT_NEAR(depthAveragedDuctExcess(0.5, 1.0), 0.122, 2e-3);
  EXPECT_LT(depthAveragedDuctExcess(5.0, 1.0), depthAveragedDuctExcess(1.5, 1.0));
  // Wide ducts: the model's side layers tend to the exact ones, the excess to 0 like 1/w.
  EXPECT_LT(depthAveragedDuctExcess(100.0, 1.0), 1e-3);
  EXPECT_THROW(ductFlowFactorExact(0.0, 1.0), std::invalid_argument);
}

TEST(DuctFlow, ImageKindReportsTheExcessAtTheNarrowestThroatAndWarns) {
  // A 2 px slot at 10 um/px in a 20 um deep chip: a 20 x 20 um throat, excess +8.5 %: warned.
  const RunOutput narrow = runSlot(2, "depth-averaged");
  ASSERT_TRUE(narrow.details.contains("depth_model_throat"));
  EXPECT_NEAR(narrow.details["depth_model_throat"]["width_over_depth"].get<double>(), 1.0, 1e-12);
  EXPECT_NEAR(narrow.details["depth_model_throat"]["duct_excess"].get<double>(), depthAveragedDuctExcess(1.0, 1.0), 1e-12);
  EXPECT_TRUE(hasWarningWith(narrow, "depth-averaged model carries 8.5 % more flow"));
  // A 10 px slot (100 um, w = 5 h): +1.2 %, reported but not warned.
  const RunOutput wide = runSlot(10, "depth-averaged");
  ASSERT_TRUE(wide.details.contains("depth_model_throat"));
  EXPECT_NEAR(wide.details["depth_model_throat"]["duct_excess"].get<double>(), depthAveragedDuctExcess(5.0, 1.0), 1e-12);
  EXPECT_LT(wide.details["depth_model_throat"]["duct_excess"].get<double>(), 0.03);
  EXPECT_FALSE(hasWarningWith(wide, "more flow"));
  // Plane 2D only: no depth model, no check.
  EXPECT_FALSE(runSlot(2, "2d").details.contains("depth_model_throat"));
}
