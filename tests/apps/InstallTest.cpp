// `cmake --install` into a prefix under the build folder, then the installed
// mmval used as someone without the source tree would: from a folder outside
// it, finding its reference data, example cases and the shared data sets those
// cases read in PREFIX/share/mmval. Kept to seconds: the installed mmval
// validates one cheap default case (plane Poiseuille, exact solution), runs one
// coarse Pore2Chip case on the installed mask and checks every installed case
// file; the whole `validate --tag default` (minutes) is measured by hand, not here.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "../TestScratch.hpp"
#include "RunMmval.hpp"

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;
using mmval::test::Outcome;

namespace {

std::string readFile(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// Runs a shell command; its exit status and output (stdout and stderr).
Outcome shell(const std::string& cmd) {
  Outcome o;
  FILE* pipe = popen((cmd + " 2>&1").c_str(), "r");
  char buf[4096];
  while (std::fgets(buf, sizeof buf, pipe) != nullptr) o.output += buf;
  const int raw = pclose(pipe);
  o.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  return o;
}

/// True when the configure step found shared data set `set` and installs it
/// (MMVAL_INSTALLED_SHARED_SETS: the set names, comma-separated).
bool sharedSetInstalled(const std::string& set) {
  std::stringstream list(MMVAL_INSTALLED_SHARED_SETS);
  for (std::string s; std::getline(list, s, ',');)
    if (s == set) return true;
  return false;
}

/// Installs the build tree into a fresh prefix for this test.
fs::path installFresh(const std::string& name) {
  const fs::path prefix = mmval::test::freshTestFolder("install", name) / "prefix";
  const Outcome o = shell(std::string("\"") + MMVAL_CMAKE_COMMAND + "\" --install \"" + MMVAL_BINARY_DIR + "\" --prefix \"" + prefix.string() + "\"");
  EXPECT_EQ(o.status, 0) << o.output;
  return prefix;
}

/// The installed mmval run from `cwd` with MMVAL_DATA_DIR unset, unless `env` sets it.
Outcome installed(const fs::path& prefix, const fs::path& cwd, const std::string& args, const std::string& env = "") {
  return shell("cd \"" + cwd.string() + "\" && env -u MMVAL_DATA_DIR " + env + " \"" + (prefix / "bin" / "mmval").string() + "\" " + args);
}

/// A folder for the installed mmval to work in, outside the source tree (and the build tree).
fs::path outsideFolder(const std::string& name) {
  const fs::path d = mmval::test::scratch(name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

TEST(Install, PrefixHoldsTheCommandDataCasesManPageAndCompletion) {
  const fs::path p = installFresh("layout");
  EXPECT_TRUE(fs::is_regular_file(p / "bin" / "mmval"));
  const fs::path share = p / "share" / "mmval";
  EXPECT_TRUE(fs::is_regular_file(share / "reference-data" / "README.md"));
  EXPECT_TRUE(fs::is_regular_file(share / "reference-data" / "schaefer-turek-2d.toml"));
  EXPECT_TRUE(fs::is_regular_file(p / "share" / "doc" / "mmval" / "LICENSE"));
  EXPECT_TRUE(fs::is_regular_file(p / "share" / "doc" / "mmval" / "CITATION.cff"));

  // Every source case is either installed or listed as left out, never both;
  // the installed ones read nothing outside the installation.
  const std::string left_out = readFile(share / "cases" / "NOT-INSTALLED.txt");
  int installed_count = 0;
  for (const auto& e : fs::directory_iterator(fs::path(MMVAL_SOURCE_DIR) / "cases")) {
    if (e.path().extension() != ".toml") continue;
    const std::string name = e.path().filename().string();
    const bool there = fs::exists(share / "cases" / name);
    const bool in_list = left_out.find("\n" + name + ": ") != std::string::npos;
    EXPECT_NE(there, in_list) << name;
    installed_count += there;
    if (there) {
      const std::string text = readFile(share / "cases" / name);
      EXPECT_THAT(text, Not(HasSubstr("../../"))) << name;
      // Paths into the installed shared data name files that were installed.
      const std::regex shared_path("\"(\\.\\./shared-data/[^\"]+)\"");
      for (auto it = std::sregex_iterator(text.begin(), text.end(), shared_path); it != std::sregex_iterator(); ++it)
        EXPECT_TRUE(fs::is_regular_file(share / "cases" / (*it)[1].str())) << name << ": " << (*it)[1].str();
    }
    if (in_list) {
      EXPECT_THAT(readFile(e.path()), HasSubstr("../../")) << name;
    }
  }
  EXPECT_GT(installed_count, 10);
  // The Pore2Chip cases are installed exactly when their data set is.
  EXPECT_EQ(fs::exists(share / "cases" / "fluid-pore2chip.toml"), sharedSetInstalled("pore2chip"));
  EXPECT_EQ(left_out.find("\nfluid-pore2chip.toml: ") != std::string::npos, !sharedSetInstalled("pore2chip"));

  const std::string man = readFile(p / "share" / "man" / "man1" / "mmval.1");
  EXPECT_THAT(man, HasSubstr(".TH MMVAL 1"));
  for (const char* sub : {".SS mmval init", ".SS mmval run", ".SS mmval validate", ".SS mmval peer openfoam", ".SS mmval track", "--set", "MMVAL_DATA_DIR"})
    EXPECT_THAT(man, HasSubstr(sub));
  // The page renders without warnings where man is installed.
  if (shell("command -v man").status == 0) {
    const Outcome render = shell("MANWIDTH=100 man --warnings -l \"" + (p / "share" / "man" / "man1" / "mmval.1").string() + "\" > /dev/null");
    EXPECT_EQ(render.output, "") << render.output;
  }

  // The completion completes subcommands, a subcommand's flags and case kinds.
  const fs::path completion = p / "share" / "bash-completion" / "completions" / "mmval";
  const auto complete = [&](const std::string& words, int cword) {
    return shell("bash -c 'source \"" + completion.string() + "\"; COMP_WORDS=(" + words + "); COMP_CWORD=" + std::to_string(cword) +
                 "; _mmval; printf \"%s\\n\" \"${COMPREPLY[@]}\"'")
        .output;
  };
  EXPECT_EQ(complete("mmval va", 1), "validate\n");
  EXPECT_THAT(complete("mmval run --s", 2), HasSubstr("--set\n"));
  EXPECT_THAT(complete("mmval validate --", 2), HasSubstr("--cases\n"));
  EXPECT_THAT(complete("mmval peer openfoam --n", 3), HasSubstr("--np\n"));
  EXPECT_THAT(complete("mmval init chan", 2), HasSubstr("channel\n"));
}

TEST(Install, InstalledMmvalValidatesFromAFolderOutsideTheSourceTree) {
  const fs::path p = installFresh("use");
  const fs::path share = fs::weakly_canonical(p / "share" / "mmval");
  const fs::path work = outsideFolder("installed-mmval");

  // Without --cases, validate reads the installed cases (the tag matches none,
  // so nothing runs: the message names the folder it read).
  const Outcome none = installed(p, work, "validate --tag no-such-tag --out out-none");
  EXPECT_EQ(none.status, 2) << none.output;
  EXPECT_THAT(none.output, HasSubstr((share / "cases").string()));

  // Every installed case resolves, reference pointers into the installed reference-data/ included.
  std::string files;
  for (const auto& e : fs::directory_iterator(share / "cases"))
    if (e.path().extension() == ".toml") files += " \"" + e.path().string() + "\"";
  const Outcome check = installed(p, work, "case-check" + files);
  EXPECT_EQ(check.status, 0) << check.output;

  // One cheap default case (plane Poiseuille, exact q = G W^3 / (12 mu)) and one
  // whose reference is a pointer ("../reference-data/shallow-channels.toml"),
  // copied into a cases folder of the user's: the pointer falls back to the
  // installed reference-data/.
  fs::create_directories(work / "cases");
  for (const char* name : {"fluid-poiseuille.toml", "fluid-shallow-duct.toml"}) fs::copy_file(share / "cases" / name, work / "cases" / name);
  const Outcome v = installed(p, work, "validate --cases cases --out out --quiet");
  EXPECT_EQ(v.status, 0) << v.output;
  EXPECT_THAT(v.output, HasSubstr("validate: 2 case(s) from cases"));
  std::ifstream in(work / "out" / "metrics.json");
  ASSERT_TRUE(in) << v.output;
  const nlohmann::json m = nlohmann::json::parse(in);
  EXPECT_EQ(m["all_pass"], true) << m.dump(2);
  EXPECT_TRUE(fs::is_regular_file(work / "out" / "index.html"));
  std::set<std::string> sources;
  for (const auto& row : m["metrics"])
    if (row.contains("source") && row["source"].is_string()) sources.insert(row["source"].get<std::string>());
  EXPECT_FALSE(sources.empty()) << m.dump(2);

  // MMVAL_DATA_DIR overrides the lookup; a wrong one is an input error naming it.
  const Outcome wrong = installed(p, work, "validate --out out-wrong", "MMVAL_DATA_DIR=" + work.string());
  EXPECT_EQ(wrong.status, 2) << wrong.output;
  EXPECT_THAT(wrong.output, HasSubstr("MMVAL_DATA_DIR"));
  const Outcome via_env = installed(p, work, "validate --tag no-such-tag --out out-env", "MMVAL_DATA_DIR=" + std::string(MMVAL_SOURCE_DIR));
  EXPECT_THAT(via_env.output, HasSubstr(std::string(MMVAL_SOURCE_DIR) + "/cases"));
  fs::remove_all(work);
}

// A case that reads the Pore2Chip mask ("../../shared/data/pore2chip/..." in
// the checkout) is installed with the data set and runs from the installed copy
// alone: the mask it reads is the installed one, pixel for pixel.
TEST(Install, CasesReadingSharedDataRunFromTheInstalledCopy) {
  if (!sharedSetInstalled("pore2chip"))
    GTEST_SKIP() << "the shared data folder (../shared/data beside the checkout, MMVAL_SHARED_DATA_DIR) was absent at "
                    "configure time, so the Pore2Chip cases are not installed";
  const fs::path p = installFresh("shared-data");
  const fs::path share = fs::weakly_canonical(p / "share" / "mmval");
  const fs::path set = share / "shared-data" / "pore2chip";
  const fs::path mask = set / "grain_network.png";
  ASSERT_TRUE(fs::is_regular_file(mask));
  EXPECT_THAT(readFile(set / "PROVENANCE.md"), HasSubstr("Pore2Chip"));
  EXPECT_TRUE(fs::is_regular_file(set / "LICENSE.md"));

  const fs::path installed_case = share / "cases" / "fluid-pore2chip.toml";
  const std::string text = readFile(installed_case);
  EXPECT_THAT(text, HasSubstr("mask = \"../shared-data/pore2chip/grain_network.png\""));
  EXPECT_THAT(text, Not(HasSubstr("shared/data")));
  EXPECT_THAT(readFile(share / "cases" / "NOT-INSTALLED.txt"), Not(HasSubstr("fluid-pore2chip.toml")));

  const fs::path work = outsideFolder("installed-shared-data");
  const Outcome check = installed(p, work, "case-check \"" + installed_case.string() + "\"");
  EXPECT_EQ(check.status, 0) << check.output;
  EXPECT_THAT(check.output, HasSubstr(": ok (kind image-permeability"));

  // case-check does not open the mask; a coarse run (one depth-averaged solve at a
  // quarter cell per pixel, about 1 s) does.
  const Outcome run = installed(p, work, "run \"" + installed_case.string() +
                                             "\" --out out --quiet --set numerics.cells_per_pixel=0.25 --set numerics.depth_model=depth-averaged");
  ASSERT_EQ(run.status, 0) << run.output;
  std::ifstream in(work / "out" / "result.json");
  ASSERT_TRUE(in) << run.output;
  const nlohmann::json r = nlohmann::json::parse(in);

  // Independent reference: the pore pixels of the installed mask counted here
  // (grains dark, so pore = grey level above mid-scale).
  const cv::Mat img = cv::imread(mask.string(), cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(img.empty()) << mask;
  const double pore_fraction = static_cast<double>(cv::countNonZero(img > 127)) / static_cast<double>(img.total());
  EXPECT_EQ(r["details"]["image_pixels"], nlohmann::json::array({img.cols, img.rows})) << r["details"].dump(2);
  double porosity = -1;
  for (const auto& m : r["metrics"])
    if (m["name"] == "porosity_total") porosity = m["value"].get<double>();
  // One pixel of 500 x 500 is 4e-6 of porosity: 2e-6 holds the two counts to the
  // same pixel while leaving room for the written value's round-off.
  EXPECT_NEAR(porosity, pore_fraction, 2e-6) << r["metrics"].dump(2);
  fs::remove_all(work);
}

// The installed CMake package: a program outside the tree (tests/apps/package-consumer)
// finds mmval::core with find_package, builds, and uses it: the darcy converts to
// 2.5 x 9.869233e-13 m^2 (API definition), a tracks CSV and a VTK array read back
// what was written. The program's exit status carries those checks.
TEST(Install, CorePackageBuildsAProgramOutsideTheTree) {
  const fs::path prefix = installFresh("package");
  for (const char* f : {"lib/cmake/mmval/mmvalConfig.cmake", "lib/cmake/mmval/mmvalTargets.cmake", "include/mmval/core/Units.hpp",
                        "include/mmval/core/BuildInfo.hpp"})
    EXPECT_TRUE(fs::exists(prefix / f)) << f;
  const fs::path work = outsideFolder("install-package-consumer");
  const std::string cmake = std::string("\"") + MMVAL_CMAKE_COMMAND + "\"";
  const Outcome configure = shell(cmake + " -S \"" + (fs::path(MMVAL_SOURCE_DIR) / "tests/apps/package-consumer").string() + "\" -B \"" +
                                  (work / "build").string() + "\" -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH=\"" + prefix.string() + "\"");
  ASSERT_EQ(configure.status, 0) << configure.output;
  const Outcome build = shell(cmake + " --build \"" + (work / "build").string() + "\"");
  ASSERT_EQ(build.status, 0) << build.output;
  const Outcome run = shell("\"" + (work / "build" / "consumer").string() + "\" \"" + work.string() + "\"");
  EXPECT_EQ(run.status, 0) << run.output;
  EXPECT_THAT(run.output, HasSubstr("k 2.46731e-12 m2, particle 7"));
  fs::remove_all(work);
}

// CITATION.cff carries the project version of CMakeLists.txt.
TEST(Install, CitationVersionIsTheProjectVersion) {
  const std::string cff = readFile(fs::path(MMVAL_SOURCE_DIR) / "CITATION.cff");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(cff, m, std::regex("\nversion: \"?([0-9.]+)\"?\n"))) << cff;
  EXPECT_EQ(m[1].str(), MMVAL_PROJECT_VERSION);
  EXPECT_THAT(cff, HasSubstr("cff-version: 1.2.0"));
  EXPECT_THAT(cff, HasSubstr("license: GPL-3.0-or-later"));
}

}  // namespace
