// Which cases `mmval validate` runs for --tag / --full (validate/CaseSelection.hpp): a tag other
// than "default" leaves out its cases tagged "full" unless --full, and --full then adds only that
// tag's full cases; the default selection is unchanged (default, plus every full case with --full).
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "mmval/core/Error.hpp"
#include "mmval/simulate/Kinds.hpp"
#include "mmval/validate/CaseSelection.hpp"

#include "../TestScratch.hpp"

namespace fs = std::filesystem;
using mmval::validate::caseSelected;
using mmval::validate::casesTagged;

namespace {

const mmval::CaseKindRegistry& registry() {
  static const mmval::CaseKindRegistry r = [] {
    mmval::CaseKindRegistry reg;
    mmval::simulate::registerFluidKinds(reg);
    return reg;
  }();
  return r;
}

/// A channel case (never run here) named `name` with `tags` (a TOML array's inside).
void writeCase(const fs::path& dir, const std::string& name, const std::string& tags) {
  std::ofstream f(dir / (name + ".toml"));
  f << "[case]\nname = \"" << name << "\"\nkind = \"channel\"\ntags = [" << tags << "]\n[geometry]\nwidth = \"100 um\"\n";
}

std::vector<std::string> names(const std::vector<fs::path>& files) {
  std::vector<std::string> n;
  for (const auto& f : files) n.push_back(f.stem().string());
  std::sort(n.begin(), n.end());
  return n;
}

}  // namespace

TEST(CaseSelection, PaperTagLeavesFullCasesToFull) {
  const fs::path dir = mmval::test::scratch("selection");
  fs::remove_all(dir);
  fs::create_directories(dir);
  writeCase(dir, "paper-short", "\"paper\"");
  writeCase(dir, "paper-long", "\"paper\", \"full\"");
  writeCase(dir, "other", "\"default\"");
  writeCase(dir, "other-long", "\"full\"");
  using V = std::vector<std::string>;
  EXPECT_EQ(names(casesTagged(dir, "paper", false, registry())), (V{"paper-short"}));
  EXPECT_EQ(names(casesTagged(dir, "paper", true, registry())), (V{"paper-long", "paper-short"}));
  // The default selection as before: default, and with --full every case tagged full.
  EXPECT_EQ(names(casesTagged(dir, "default", false, registry())), (V{"other"}));
  EXPECT_EQ(names(casesTagged(dir, "default", true, registry())), (V{"other", "other-long", "paper-long"}));
  EXPECT_EQ(names(casesTagged(dir, "all", false, registry())).size(), 4u);
  EXPECT_TRUE(mmval::validate::fullOnlyTag(dir, "paper", registry()));
  EXPECT_FALSE(mmval::validate::fullOnlyTag(dir, "default", registry()));
}

TEST(CaseSelection, Rule) {
  using V = std::vector<std::string>;
  EXPECT_TRUE(caseSelected(V{"default"}, "default", false));
  EXPECT_FALSE(caseSelected(V{"full"}, "default", false));
  EXPECT_TRUE(caseSelected(V{"full"}, "default", true));
  EXPECT_TRUE(caseSelected(V{"table3", "full"}, "table3", true));
  EXPECT_FALSE(caseSelected(V{"table3", "full"}, "table3", false));
  EXPECT_FALSE(caseSelected(V{"full"}, "paper", true));  // --full adds the tag's full cases only
  EXPECT_TRUE(caseSelected(V{"full"}, "full", false));
  EXPECT_TRUE(caseSelected(V{}, "all", false));
}
