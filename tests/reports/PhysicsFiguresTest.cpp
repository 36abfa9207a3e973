// The physics checks' figures in the report (PhysicsFigures.cpp): every check kind,
// run small from its shipped case, gets its figure on its own case page, drawn
// against its theory, with the run's CSV linked behind it and every link of the
// site resolving. Also the two pieces of the plotting they need: error bars and
// CSV rows whose last cell is empty.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "../particles/ParticleRegistry.hpp"
#include "../TestScratch.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/reports/PhysicsFigures.hpp"
#include "mmval/reports/Plot.hpp"
#include "mmval/reports/Report.hpp"
#include "mmval/reports/Site.hpp"
#include "mmval/reports/Tables.hpp"

namespace mmval::reports {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream b;
  b << in.rdbuf();
  return b.str();
}

/// A shipped physics case, made small by overrides (each run ~1 s): what the figure needs, not the check's accuracy.
struct SmallRun {
  std::string case_file;               ///< under cases/
  std::vector<CaseOverride> overrides;
  std::vector<std::string> figures;  ///< figure ids on its page
  std::string csv;                   ///< the run's CSV linked behind the first figure
};

const std::vector<SmallRun>& smallRuns() {
  static const std::vector<SmallRun> runs = {
      {"physics-sedimentation-equilibrium", {{"particles.count", "20"}, {"run.equilibration", "5 s"}, {"run.duration", "25 s"}}, {"height-histogram"},
       "height_histogram.csv"},
      {"physics-hindered-diffusion", {{"release.particles", "200"}, {"release.heights", "[1.5431, 3.7622]"}}, {"hindered-diffusion"}, "hindered_diffusion.csv"},
      {"physics-blocking", {{"run.attempted_coverage", "0.3"}, {"domain.size", "100 um"}}, {"coverage"}, "coverage.csv"},
      {"physics-settling-slit", {{"particles.count", "10"}, {"analysis.points", "10"}}, {"settling-fraction"}, "settling-deposition.csv"},
      {"physics-diffusion-slit", {{"particles.count", "200"}, {"numerics.step_check_factor", "0"}}, {"penetration"}, "diffusion-penetration.csv"},
      {"physics-collector-interception", {{"sweep.interception", "[0.05, 0.1]"}, {"search.rounds", "2"}, {"search.particles", "4"}}, {"eta-vs-R"},
       "collector-interception.csv"},
      {"physics-collector-diffusion", {{"sweep.peclet", "[200, 600]"}, {"particles.count", "200"}}, {"eta-vs-Pe"}, "collector-diffusion.csv"},
      {"physics-dlvo", {}, {"dlvo-profile", "attachment-vs-ionic-strength"}, "dlvo-profile.csv"},
      {"physics-near-wall-shear", {}, {"translation"}, "near-wall-shear.csv"},
  };
  return runs;
}

/// The small runs under <scratch>/physics/runs/<case> and the report of them in <scratch>/physics/report; built once.
const fs::path& physicsReport() {
  static const fs::path out = [] {
    const fs::path root = mmval::test::scratch("physics");
    fs::remove_all(root);
    auto& registry = particles::test_support::particleRegistry();
    for (const auto& r : smallRuns()) {
      const Case c = Case::load(fs::path(MMVAL_SOURCE_DIR) / "cases" / (r.case_file + ".toml"), registry, r.overrides);
      runCase(c, registry, root / "runs" / r.case_file, {.quiet = true});
    }
    writeReport(collect({root}), root / "report");
    return root / "report";
  }();
  return out;
}

TEST(PhysicsFigures, EveryCheckKindHasItsFigureAndCsvOnItsCasePage) {
  if (!gnuplotAvailable()) GTEST_SKIP() << "gnuplot not installed";
  const fs::path& report = physicsReport();
  for (const auto& r : smallRuns()) {
    SCOPED_TRACE(r.case_file);
    const std::string page = slurp(report / "cases" / (r.case_file + ".html"));
    for (const auto& id : r.figures) {
      const std::string fig = r.case_file + "-" + id;
      EXPECT_TRUE(fs::exists(report / "figures" / (fig + ".svg"))) << fig;
      EXPECT_THAT(page, HasSubstr("<figure id=\"fig-" + fig + "\">"));
    }
    // The run's own CSV behind the figure, linked from the page relative to it.
    EXPECT_THAT(page, HasSubstr("[data: <a href=\"../../runs/" + r.case_file + "/" + r.csv + "\">" + r.csv + " (CSV)</a>]"));
  }
  EXPECT_THAT(brokenLinks(report), ::testing::IsEmpty());
}

TEST(PhysicsFigures, TheoryComesFromReferenceData) {
  if (!gnuplotAvailable()) GTEST_SKIP() << "gnuplot not installed";
  const fs::path& report = physicsReport();
  // Blocking: the jamming levels of reference-data/rsa-blocking.toml (RSA 0.547, BD 0.6105) drawn as lines.
  const std::string coverage = slurp(report / "figures" / "physics-blocking-coverage.svg");
  EXPECT_THAT(coverage, HasSubstr("random sequential adsorption jamming 0.547"));
  EXPECT_THAT(coverage, HasSubstr("jamming (Talbot &amp; Ricci 1992) 0.6105"));
  // Hindered diffusion: Faxen's series and Brenner's solution from reference-data/wall-hydrodynamics.toml.
  const std::string hindered = slurp(report / "figures" / "physics-hindered-diffusion-hindered-diffusion.svg");
  EXPECT_THAT(hindered, HasSubstr("Faxen series, parallel"));
  EXPECT_THAT(hindered, HasSubstr("Brenner (1961), normal"));
}

TEST(PhysicsFigures, OtherKindsGetNoCheckFigure) {
  const fs::path dir = mmval::test::scratch("not-physics");
  fs::create_directories(dir);
  std::ofstream(dir / "height_histogram.csv") << "z_um,count,density_1_per_um,boltzmann_density_1_per_um\n1,2,3,4\n";
  const nlohmann::json run{{"run_dir", dir.string()}, {"case", {{"name", "x"}, {"kind", "particles-channel"}}}, {"metrics", nlohmann::json::array()}};
  EXPECT_TRUE(physicsCheckFigures(run, {}).empty());
  nlohmann::json sed = run;
  sed["case"]["kind"] = "physics-sedimentation";
  ASSERT_EQ(physicsCheckFigures(sed, {}).size(), 1u);
  EXPECT_EQ(physicsCheckFigures(sed, {}).front().data, dir / "height_histogram.csv");
}

TEST(Plot, ErrorBarsAreDrawnFromTheThirdColumn) {
  if (!gnuplotAvailable()) GTEST_SKIP() << "gnuplot not installed";
  Plot p{"bars", "x", "y", false, false, {}, 320, 200};
  p.series.push_back({"with bars", {1, 2, 3}, {1, 4, 9}, "yerrorbars", {0.5, 0.5, 0.5}});
  const std::string bars = renderSvg(p);
  EXPECT_THAT(bars, HasSubstr("with bars"));
  // The same points without their bars draw less.
  p.series.front().yerr.clear();
  p.series.front().style = "points";
  EXPECT_GT(bars.size(), renderSvg(p).size());
}

TEST(ReadCsvColumns, RowEndingInACommaHasAnEmptyLastCell) {
  const fs::path file = mmval::test::scratch("trailing.csv");
  std::ofstream(file) << "a,b,c\n1,2,3\n4,5,\n";
  const auto cols = readCsvColumns(file);
  ASSERT_EQ(cols.at("c").size(), 2u);
  EXPECT_DOUBLE_EQ(cols.at("b")[1], 5.0);
  EXPECT_TRUE(std::isnan(cols.at("c")[1]));
  std::ofstream(file) << "a,b,c\n1,2\n";
  EXPECT_THROW(readCsvColumns(file), InputError);
}

}  // namespace
}  // namespace mmval::reports
