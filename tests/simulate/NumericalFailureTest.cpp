// Numerical failures a user can fix, through the fluid case kinds on 1 MPI rank: a
// gap narrower than one cell is a NumericalFailure (exit 5) naming the resolution key before
// anything is solved, a throat narrower than two cells a warning in details.warnings; exit 4 is
// left for bugs. Integration tier: small grids, seconds.
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "mmval/core/Error.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/simulate/Kinds.hpp"

#include "../TestScratch.hpp"
#include "FluidRegistry.hpp"

namespace fs = std::filesystem;
using namespace mmval;

namespace {

const CaseKindRegistry& registry() { return test_support::fluidRegistry(); }

RunOutput run(const Case& c) { return registry().find(c.kind())->run(c, RunContext{{}, true, false, 0}); }

/// A 40 x 20 pixel mask (10 um pixels), fluid but for a grain wall across column 19 with a
/// one-pixel throat at row 10: all the flow passes that pixel.
fs::path onePixelThroatMask() {
  const fs::path p = mmval::test::scratch("one-pixel-throat.pgm");
  std::ofstream f(p, std::ios::binary);
  f << "P5\n40 20\n255\n";
  for (int r = 0; r < 20; ++r)
    for (int c = 0; c < 40; ++c) f.put(static_cast<char>(c == 19 && r != 10 ? 0 : 255));
  return p;
}

Case maskCase(double cells_per_pixel) {
  const std::string text = "[case]\nname = \"throat\"\nkind = \"image-permeability\"\n[geometry]\nmask = \"" + onePixelThroatMask().string() +
                           "\"\npixel_size = \"10 um\"\n[numerics]\ndepth_model = \"2d\"\ncells_per_pixel = " + std::to_string(cells_per_pixel) + "\n";
  return Case::parse(text, mmval::test::scratch("throat.toml"), registry());
}

}  // namespace

TEST(NumericalFailure, SquareArrayGapUnderOneCellNamesTheResolutionKey) {
  // phi 0.75 at 32 cells: the gap between neighbouring cylinders is 0.0228 L = 0.73 cells.
  Case c = Case::load(fs::path(MMVAL_SOURCE_DIR) / "cases" / "fluid-square-array-phi020.toml", registry());
  c.set("geometry.solid_fraction", 0.75);
  c.set("numerics.levels", std::vector<std::int64_t>{32});
  try {
    run(c);
    FAIL() << "phi 0.75 at 32 cells ran";
  } catch (const NumericalFailure& e) {
    EXPECT_EQ(e.key(), "numerics.levels") << e.what();
    EXPECT_NE(std::string(e.what()).find("cells wide"), std::string::npos) << e.what();
  }
}

TEST(NumericalFailure, OnePixelThroatAtHalfACellPerPixelFails) {
  try {
    run(maskCase(0.5));
    FAIL() << "a one-pixel throat at 0.5 cells per pixel ran";
  } catch (const NumericalFailure& e) {
    EXPECT_EQ(e.key(), "numerics.cells_per_pixel") << e.what();
    EXPECT_NE(std::string(e.what()).find("0.50 cells wide"), std::string::npos) << e.what();
  }
}

TEST(NumericalFailure, OnePixelThroatAtOneCellPerPixelWarns) {
  const RunOutput out = run(maskCase(1.0));
  ASSERT_TRUE(out.details.contains("warnings"));
  const std::string w = out.details["warnings"][0].get<std::string>();
  EXPECT_NE(w.find("1.00 cells wide"), std::string::npos) << w;
  EXPECT_NE(w.find("numerics.cells_per_pixel"), std::string::npos) << w;
}
