// One vocabulary on the command line: options say what the case keys say
// (geometry.y_up, geometry.grains dark | bright, a pixel size in --*pixel-size-um).
// The older spellings (--mask-y-down, --mask-grains, "light", chip's --pixel-um)
// still work, give the same result as the new ones, stay out of --help and print
// one line naming the replacement.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "RunMmval.hpp"

#include <filesystem>
#include <fstream>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;
using mmval::test::Outcome;

constexpr int kMaskCols = 60, kMaskRows = 40, kGrainRows = 10;  // 1 um pixels; grains: the top kGrainRows rows

/// A PGM mask whose top kGrainRows rows are dark (grains) and the rest bright (pore).
void writeMask(const fs::path& file) {
  std::ofstream out(file);
  out << "P2\n" << kMaskCols << ' ' << kMaskRows << "\n255\n";
  for (int r = 0; r < kMaskRows; ++r)
    for (int c = 0; c < kMaskCols; ++c) out << (r < kGrainRows ? 0 : 255) << (c + 1 == kMaskCols ? '\n' : ' ');
}

/// Three particles moving along x at 10 um/s for 1.9 s from x = 5 um, at y = 3, 6 and 35 um:
/// each stays in one row band of the mask for its whole track.
std::string tracksAtThreeHeights() {
  std::string rows = "frame,particle,t_s,x_um,y_um\n";
  const double heights_um[] = {3, 6, 35};
  for (int i = 0; i < 3; ++i)
    for (int f = 0; f < 20; ++f) rows += fmt::format("{},{},{:.1f},{:g},{:g}\n", f, i + 1, 0.1 * f, 5 + 1.0 * f, heights_um[i]);
  return rows;
}

struct Folder {
  fs::path dir;
  Folder() : dir(mmval::test::freshTestFolder("cli-vocabulary", ::testing::UnitTest::GetInstance()->current_test_info()->name())) {
    writeMask(dir / "mask.pgm");
    std::ofstream(dir / "tracks.csv") << tracksAtThreeHeights();
  }
  /// `mmval compare` of the tracks against themselves over the mask, with `options`, into dir/out-NAME.
  Outcome compare(const std::string& name, const std::string& options) const {
    return mmval::test::runMmval(fmt::format("compare --experiment {0} --simulation {0} --mask {1} --mask-pixel-size-um 1 --out {2} {3}",
                                             (dir / "tracks.csv").string(), (dir / "mask.pgm").string(), (dir / ("out-" + name)).string(), options));
  }
  nlohmann::json metrics(const std::string& name) const {
    std::ifstream in(dir / ("out-" + name) / "metrics.json");
    return nlohmann::json::parse(in);
  }
  double stepsInGrains(const std::string& name) const {
    const nlohmann::json all = metrics(name);
    for (const auto& m : all["metrics"])
      if (m["name"] == "experiment_steps_in_grains") return m["value"].get<double>();
    ADD_FAILURE() << "no experiment_steps_in_grains in out-" << name;
    return -1;
  }
};

// The fractions below are counts: with y down from the top-left corner, the particles at
// y = 3 and 6 um sit in the grain rows (0-9) and the one at 35 um in the pore: 2 of 3.
// With y up from the lower-left corner, y = 35 um is row 40 - 35 = 5 (grain) and the others
// rows 36 and 33 (pore): 1 of 3. Exact ratios of small counts, so 1e-12 (round-off).
constexpr double kCountTolerance = 1e-12;

TEST(CliVocabulary, YUpFalseAndOlderMaskYDownGiveTheSameComparison) {
  const Folder f;
  const Outcome now = f.compare("y-up-false", "--y-up false");
  const Outcome older = f.compare("mask-y-down", "--mask-y-down");
  const Outcome up = f.compare("default", "");
  ASSERT_EQ(now.status, 0) << now.output;
  ASSERT_EQ(older.status, 0) << older.output;
  ASSERT_EQ(up.status, 0) << up.output;
  EXPECT_NEAR(f.stepsInGrains("y-up-false"), 2.0 / 3.0, kCountTolerance);
  EXPECT_NEAR(f.stepsInGrains("default"), 1.0 / 3.0, kCountTolerance);  // the flag is not ignored: y up is the default
  EXPECT_EQ(f.metrics("y-up-false"), f.metrics("mask-y-down"));
  EXPECT_THAT(older.output, HasSubstr("mmval: note: --mask-y-down is an older spelling; use --y-up false"));
  EXPECT_THAT(now.output, Not(HasSubstr("note:")));
}

TEST(CliVocabulary, GrainPixelsBrightAndOlderMaskGrainsLightGiveTheSameComparison) {
  const Folder f;
  const Outcome now = f.compare("bright", "--y-up false --grain-pixels bright");
  const Outcome older = f.compare("light", "--mask-y-down --mask-grains light");
  ASSERT_EQ(now.status, 0) << now.output;
  ASSERT_EQ(older.status, 0) << older.output;
  // Bright pixels as grains: the pore rows of the mask become the grains, 1 of 3 tracks in them.
  EXPECT_NEAR(f.stepsInGrains("bright"), 1.0 / 3.0, kCountTolerance);
  EXPECT_EQ(f.metrics("bright"), f.metrics("light"));
  EXPECT_THAT(older.output, HasSubstr("mmval: note: --mask-grains light is an older spelling; use --grain-pixels bright"));
}

TEST(CliVocabulary, NewAndOlderSpellingTogetherIsAUsageError) {
  const Folder f;
  const Outcome both = f.compare("both", "--y-up true --mask-y-down");
  EXPECT_EQ(both.status, 1) << both.output;
  EXPECT_THAT(both.output, HasSubstr("--y-up excludes --mask-y-down"));
  EXPECT_FALSE(fs::exists(f.dir / "out-both"));
}

TEST(CliVocabulary, RegisterMaskIsTheOlderSpellingOfMask) {
  const Folder f;
  const Outcome now = f.compare("mask", "");
  const Outcome older = mmval::test::runMmval(fmt::format("compare --experiment {0} --simulation {0} --register-mask {1} --mask-pixel-size-um 1 --out {2}",
                                                          (f.dir / "tracks.csv").string(), (f.dir / "mask.pgm").string(), (f.dir / "out-register-mask").string()));
  ASSERT_EQ(now.status, 0) << now.output;
  ASSERT_EQ(older.status, 0) << older.output;
  EXPECT_NEAR(f.stepsInGrains("register-mask"), 1.0 / 3.0, kCountTolerance);  // the mask was read: y up, 1 of 3 in grains
  EXPECT_EQ(f.metrics("mask"), f.metrics("register-mask"));
  EXPECT_THAT(older.output, HasSubstr("is an older spelling; use --mask"));
  const Outcome both = f.compare("mask-twice", "--register-mask " + (f.dir / "mask.pgm").string());
  EXPECT_EQ(both.status, 1) << both.output;
  EXPECT_THAT(both.output, HasSubstr("--mask excludes --register-mask"));
}

TEST(CliVocabulary, HelpShowsOnlyTheCaseVocabulary) {
  const Outcome compare = mmval::test::runMmval("compare --help");
  EXPECT_THAT(compare.output, HasSubstr("--y-up"));
  EXPECT_THAT(compare.output, HasSubstr("--grain-pixels TEXT:{dark,bright}"));
  for (const char* older : {"--mask-y-down", "--mask-grains", "light", "--register-mask"}) EXPECT_THAT(compare.output, Not(HasSubstr(older))) << older;
  const Outcome chip = mmval::test::runMmval("chip --help");
  EXPECT_THAT(chip.output, HasSubstr("--pixel-size-um"));
  EXPECT_THAT(chip.output, Not(HasSubstr("--pixel-um")));
}

TEST(CliVocabulary, ChipPixelUmIsTheOlderSpellingOfPixelSizeUm) {
  const fs::path d = mmval::test::freshTestFolder("cli-vocabulary", "chip");
  // A pixel size of 0 is refused before any work: both spellings reach the same check.
  const Outcome now = mmval::test::runMmval(fmt::format("chip --quiet --pixel-size-um 0 --out {}", (d / "now").string()));
  const Outcome older = mmval::test::runMmval(fmt::format("chip --quiet --pixel-um 0 --out {}", (d / "older").string()));
  EXPECT_EQ(now.status, 2) << now.output;
  EXPECT_EQ(older.status, 2) << older.output;
  EXPECT_THAT(now.output, HasSubstr("a pixel size in um, > 0"));
  EXPECT_THAT(older.output, HasSubstr("a pixel size in um, > 0"));
  EXPECT_THAT(older.output, HasSubstr("mmval: note: --pixel-um is an older spelling; use --pixel-size-um"));
  EXPECT_THAT(now.output, Not(HasSubstr("note:")));
}

}  // namespace
