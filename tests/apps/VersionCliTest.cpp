// `mmval --version` prints the commit the binary was built from: the source
// tree's git HEAD when the sources are a git checkout (the build stamps it at
// every build, cmake/WriteBuildInfo.cmake).
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <regex>
#include <string>

#include "RunMmval.hpp"
#include "mmval/core/BuildInfo.hpp"

namespace mmval {
namespace {

namespace fs = std::filesystem;

/// The first line `cmd` prints on stdout ("" when it fails).
std::string firstLine(const std::string& cmd) {
  FILE* pipe = popen((cmd + " 2>/dev/null").c_str(), "r");
  if (pipe == nullptr) return "";
  std::string text;
  std::array<char, 512> buf{};
  while (std::fgets(buf.data(), buf.size(), pipe) != nullptr) text += buf.data();
  return pclose(pipe) == 0 ? text.substr(0, text.find('\n')) : "";
}

TEST(VersionCli, PrintsTheCommitTheSourcesAreAt) {
  const test::Outcome o = test::runMmval("--version");
  ASSERT_EQ(o.status, 0) << o.output;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(o.output, m, std::regex(R"(^mmval (\S+) \(([0-9a-f]{12}(-dirty)?|unknown), )"))) << o.output;
  EXPECT_EQ(m[1].str(), build::kVersion);
  const std::string printed = m[2].str();

  const std::string git = MMVAL_GIT_EXECUTABLE, src = MMVAL_SOURCE_DIR;
  if (git.empty() || git.find("NOTFOUND") != std::string::npos) GTEST_SKIP() << "git was not found when the build was configured";
  const std::string top_dir = firstLine("'" + git + "' -C '" + src + "' rev-parse --show-toplevel");
  std::error_code ec;
  if (top_dir.empty() || !fs::equivalent(top_dir, src, ec)) GTEST_SKIP() << src << " is not a git checkout: --version says " << printed;
  const std::string head_hash = firstLine("'" + git + "' -C '" + src + "' rev-parse --short=12 HEAD");
  ASSERT_FALSE(head_hash.empty());
  EXPECT_EQ(printed.substr(0, printed.find("-dirty")), head_hash) << "rebuild mmval: it was built from another commit";
}

}  // namespace
}  // namespace mmval
