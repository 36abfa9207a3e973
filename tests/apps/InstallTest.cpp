// `cmake --install` into a prefix under the build folder, then the installed
// mmval used as someone without the source tree would: from a folder outside
// it, finding its reference data and example cases in PREFIX/share/mmval.
// Kept to seconds: the installed mmval validates one cheap default case
// (plane Poiseuille, exact solution) and checks every installed case file; the
// whole `validate --tag default` (minutes) is measured by hand, not here.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

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
  int installed_count = 0, listed = 0;
  for (const auto& e : fs::directory_iterator(fs::path(MMVAL_SOURCE_DIR) / "cases")) {
    if (e.path().extension() != ".toml") continue;
    const std::string name = e.path().filename().string();
    const bool there = fs::exists(share / "cases" / name);
    const bool in_list = left_out.find("\n" + name + ": ") != std::string::npos;
    EXPECT_NE(there, in_list) << name;
    installed_count += there;
    listed += in_list;
    if (there) {
      EXPECT_THAT(readFile(share / "cases" / name), Not(HasSubstr("../../"))) << name;
    }
    if (in_list) {
      EXPECT_THAT(readFile(e.path()), HasSubstr("../../")) << name;
    }
  }
  EXPECT_GT(installed_count, 10);
  EXPECT_THAT(left_out, HasSubstr("fluid-pore2chip.toml: "));

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
